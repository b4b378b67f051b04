//! Light tracing (`--integrator light`, and `light-guided` with W learned by a hemisphere
//! grid or a spatial × directional tree) against next-event estimation: on cornell they
//! estimate one image, so their per-image means agree within 4 standard errors, and their
//! per-pixel difference is at the level of two nee renders' noise (a light path splatted
//! into the wrong pixel, or with a wrong importance or guide pdf, shows there).

mod support;

use guiding_core::{HemisphereGridSettings, SpatialDirectionalTreeSettings};
use reference_tracer::integrator::{IntegratorSettings, Method};
use support::{
    assert_agree, mean_estimate, quadrant_mean, relative_difference, render_image, render_scheduled, repository_scene,
    settings, Schedule,
};

#[test]
fn light_tracing_renders_cornell_as_nee_does() {
    let scene = repository_scene("cornell", 24, 24);
    let spp = 256;
    let (nee, nee_stats) = render_image(&scene, settings(Method::Nee), None, spp, 11);
    let (again, _) = render_image(&scene, settings(Method::Nee), None, spp, 12);
    let noise = relative_difference(&nee, &again);
    let grid = HemisphereGridSettings { probe_count: Some(40), ..Default::default() };
    let tree = SpatialDirectionalTreeSettings::default();
    let cases =
        [(Method::Light, None), (Method::LightGuided, Some(grid.into())), (Method::LightGuided, Some(tree.into()))];
    for (method, guide) in cases {
        let integrator = IntegratorSettings { guide_probability: 0.5, ..settings(method) };
        let (light, light_stats) = render_scheduled(&scene, integrator, guide, spp, 13, Schedule::Iterative);
        let label = method.name();
        assert_agree(label, &mean_estimate(&light_stats), &mean_estimate(&nee_stats));
        // Light tracing is noisier per pixel than nee on some pixels (the light seen
        // directly), so its difference may be larger, but not by an order of magnitude.
        let difference = relative_difference(&light, &nee);
        assert!(difference < 3.0 * noise, "{label} against nee {difference:.3e}, nee against nee {noise:.3e}");
        // Quadrant by quadrant: a mirrored or shifted splat would move light between them.
        for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (a, b) = (quadrant_mean(&light, qx, qy), quadrant_mean(&nee, qx, qy));
            assert!((a - b).abs() < 0.05 * b, "{label}, quadrant ({qx}, {qy}): {a} against nee's {b}");
        }
    }
}

#[test]
fn light_tracing_refuses_what_it_cannot_render() {
    let glossy = repository_scene("glossy", 16, 16);
    let lights = reference_tracer::session::LightRequest::new(None, None, false);
    let choice = reference_tracer::scene_intersector::IntersectorChoice::default();
    let mut session = reference_tracer::session::prepare_with_lights(&glossy, choice, None, lights).unwrap();
    let render = support::render_settings(settings(Method::Light), 1, 1, Schedule::Online);
    let error = session.render(&render, |_| {}).unwrap_err();
    assert!(error.contains("delta triangles"), "{error}");
    let window = repository_scene("window", 16, 16);
    let lights = reference_tracer::session::LightRequest::new(None, None, false);
    let mut session = reference_tracer::session::prepare_with_lights(&window, choice, None, lights).unwrap();
    let error = session.render(&render, |_| {}).unwrap_err();
    assert!(error.contains("environment") || error.contains("delta"), "{error}");
}

/// Cornell with one box made of a lace that lets half the light through (a masked
/// material, opacity 0.5 everywhere): light tracing's camera connections pass it as the
/// light samples of nee do, weighed by the transmittance.
#[test]
fn light_tracing_sees_through_masks_as_nee_does() {
    let scene = support::masked_cornell(24, 24);
    let spp = 256;
    let (nee, nee_stats) = render_image(&scene, settings(Method::Nee), None, spp, 21);
    let (light, light_stats) = render_image(&scene, settings(Method::Light), None, spp, 22);
    assert_agree("masked cornell, light against nee", &mean_estimate(&light_stats), &mean_estimate(&nee_stats));
    for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (a, b) = (quadrant_mean(&light, qx, qy), quadrant_mean(&nee, qx, qy));
        assert!((a - b).abs() < 0.05 * b, "masked, quadrant ({qx}, {qy}): light {a} against nee's {b}");
    }
}
