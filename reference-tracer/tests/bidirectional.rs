//! Bidirectional path tracing (`--integrator bdpt`) against next-event estimation: on
//! cornell (diffuse), masked cornell (light passing a lace) and glossy (mirrors, glass
//! and rough metal) they estimate one image, so their per-image means agree within 4
//! standard errors and, quadrant by quadrant, within a few per cent (a splat in the
//! wrong pixel, a wrong weight or a density left out shows there). That the weights of
//! every path sum to one is checked beside the integrator
//! (`integrator::bidirectional::tests`).

mod support;

use reference_tracer::integrator::Method;
use support::{
    assert_agree, mean_estimate, quadrant_mean, relative_difference, render_image, repository_scene, settings,
};

/// Renders `scene` with nee twice and bdpt once; bdpt must agree with nee as well as
/// nee agrees with itself, up to `slack` times its pixel noise.
fn agrees_with_nee(label: &str, scene: &std::path::Path, spp: u32) {
    let (nee, nee_stats) = render_image(scene, settings(Method::Nee), None, spp, 31);
    let (again, _) = render_image(scene, settings(Method::Nee), None, spp, 32);
    let noise = relative_difference(&nee, &again);
    let (bdpt, bdpt_stats) = render_image(scene, settings(Method::Bdpt), None, spp, 33);
    assert_agree(label, &mean_estimate(&bdpt_stats), &mean_estimate(&nee_stats));
    // bdpt is the less noisy per pixel (it has nee among its strategies), so its
    // difference from nee is at most nee's own.
    let difference = relative_difference(&bdpt, &nee);
    assert!(difference < 1.5 * noise, "{label}: bdpt against nee {difference:.3e}, nee against nee {noise:.3e}");
    for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (a, b) = (quadrant_mean(&bdpt, qx, qy), quadrant_mean(&nee, qx, qy));
        assert!((a - b).abs() < 0.05 * b, "{label}, quadrant ({qx}, {qy}): bdpt {a} against nee's {b}");
    }
}

#[test]
fn bdpt_renders_cornell_as_nee_does() {
    agrees_with_nee("cornell", &repository_scene("cornell", 24, 24), 256);
}

#[test]
fn bdpt_sees_through_masks_as_nee_does() {
    agrees_with_nee("masked cornell", &support::masked_cornell(24, 24), 256);
}

#[test]
fn bdpt_renders_glass_and_mirrors_as_nee_does() {
    agrees_with_nee("glossy", &repository_scene("glossy", 24, 24), 512);
}

#[test]
fn bdpt_refuses_what_it_cannot_render() {
    let window = repository_scene("window", 16, 16);
    let lights = reference_tracer::cli::LightRequest::new(None, None, false);
    let choice = reference_tracer::scene_intersector::IntersectorChoice::default();
    let mut prepared = reference_tracer::cli::prepare_with_lights(&window, choice, None, lights).unwrap();
    let render = reference_tracer::render::RenderSettings {
        integrator: settings(Method::Bdpt),
        budget: reference_tracer::render::Budget::SamplesPerPixel(1),
        seed: 1,
        train_seconds: 0.0,
        schedule: support::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    let error = prepared.render(&render, |_| {}).unwrap_err();
    assert!(error.starts_with("bdpt:") && error.contains("environment"), "{error}");
}
