//! Bidirectional path tracing (`--integrator bdpt`) against next-event estimation: on
//! cornell (diffuse), masked cornell (light passing a lace) and glossy (mirrors, glass
//! and rough metal) they estimate one image, so their per-image means agree within 4
//! standard errors and, quadrant by quadrant, within a few per cent (a splat in the
//! wrong pixel, a wrong weight or a density left out shows there). That the weights of
//! every path sum to one is checked beside the integrator
//! (`integrator::bidirectional::mis::tests`), guided and unguided.

mod support;

use guiding_core::{HemisphereGridSettings, SpatialDirectionalTreeSettings};
use reference_tracer::directional_guide::DirectionalGuideSettings;
use reference_tracer::integrator::{IntegratorSettings, Method};
use support::{
    assert_agree, mean_estimate, quadrant_mean, quadrant_standard_error, relative_difference, render_image,
    render_scheduled, repository_scene, settings, Schedule,
};

/// Renders `scene` with nee twice and bdpt once; bdpt must agree with nee as well as
/// nee agrees with itself, up to `slack` times its pixel noise.
fn agrees_with_nee(label: &str, scene: &std::path::Path, spp: u32) {
    agrees_with_nee_as(label, scene, spp, settings(Method::Bdpt));
}

fn agrees_with_nee_as(label: &str, scene: &std::path::Path, spp: u32, bdpt_settings: IntegratorSettings) {
    agrees_with_nee_guided(label, scene, spp, bdpt_settings, None);
}

/// [`agrees_with_nee_as`] with a directional guide, learned on the iterative schedule.
fn agrees_with_nee_guided(
    label: &str,
    scene: &std::path::Path,
    spp: u32,
    bdpt_settings: IntegratorSettings,
    guide: Option<DirectionalGuideSettings>,
) {
    let (nee, nee_stats) = render_image(scene, settings(Method::Nee), None, spp, 31);
    let (again, _) = render_image(scene, settings(Method::Nee), None, spp, 32);
    let noise = relative_difference(&nee, &again);
    let (bdpt, bdpt_stats) = render_scheduled(scene, bdpt_settings, guide, spp, 33, Schedule::Iterative);
    assert_agree(label, &mean_estimate(&bdpt_stats), &mean_estimate(&nee_stats));
    // bdpt is the less noisy per pixel (it has nee among its strategies), so its
    // difference from nee is at most nee's own (roulette adds noise of its own).
    let difference = relative_difference(&bdpt, &nee);
    let slack = if bdpt_settings.connection_roulette > 0.0 { 3.0 } else { 1.5 };
    assert!(difference < slack * noise, "{label}: bdpt against nee {difference:.3e}, nee against nee {noise:.3e}");
    // Quadrant by quadrant against the mean of both nee renders: within 5 %, or within 4
    // standard errors where the quadrant is noisier than that (glossy's bottom right at
    // 512 spp: about 3 % per nee render), bdpt's variance taken as `slack` times one nee render's.
    for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let a = quadrant_mean(&bdpt, qx, qy);
        let b = 0.5 * (quadrant_mean(&nee, qx, qy) + quadrant_mean(&again, qx, qy));
        let one_render = quadrant_standard_error(&nee, &again, qx, qy);
        let standard_error = (0.5 + slack).sqrt() * one_render;
        let tolerance = (0.05 * b).max(4.0 * standard_error);
        assert!(
            (a - b).abs() < tolerance,
            "{label}, quadrant ({qx}, {qy}): bdpt {a} against nee's {b} (tolerance {tolerance:.4}, standard error {standard_error:.4})"
        );
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

/// Connection roulette traces faint connections by chance and weighs them up: noisier,
/// never biased.
#[test]
fn bdpt_with_connection_roulette_renders_cornell_as_nee_does() {
    let roulette = IntegratorSettings { connection_roulette: 1.0, ..settings(Method::Bdpt) };
    agrees_with_nee_as("cornell, connection roulette 1", &repository_scene("cornell", 24, 24), 256, roulette);
}

/// bdpt-guided: camera subpaths guided by Q (a hemisphere grid, a spatial × directional
/// tree) learned from them; the guided densities enter every weight.
#[test]
fn guided_bdpt_renders_cornell_and_glossy_as_nee_does() {
    let grid = HemisphereGridSettings { probe_count: Some(40), ..Default::default() };
    let guided = IntegratorSettings { guide_probability: 0.5, ..settings(Method::BdptGuided) };
    let cornell = repository_scene("cornell", 24, 24);
    agrees_with_nee_guided("cornell, bdpt-guided grid", &cornell, 256, guided, Some(grid.into()));
    let tree = SpatialDirectionalTreeSettings::default();
    agrees_with_nee_guided("cornell, bdpt-guided tree", &cornell, 256, guided, Some(tree.into()));
    let glossy = repository_scene("glossy", 24, 24);
    agrees_with_nee_guided("glossy, bdpt-guided grid", &glossy, 512, guided, Some(grid.into()));
}

/// The caustic scene: light reaches every diffuse surface through a glass ball, which
/// next-event estimation cannot see through. bdpt's mean agrees with nee's, and its
/// per-pixel noise is a fraction of nee's at the same sample count (its light subpaths
/// carry the caustic).
#[test]
fn bdpt_renders_the_caustic_scene_with_a_fraction_of_nees_noise() {
    let scene = repository_scene("caustic", 16, 16);
    let spp = 512;
    let (nee, nee_stats) = render_image(&scene, settings(Method::Nee), None, spp, 41);
    let (nee_again, _) = render_image(&scene, settings(Method::Nee), None, spp, 42);
    let (bdpt, bdpt_stats) = render_image(&scene, settings(Method::Bdpt), None, spp, 43);
    let (bdpt_again, _) = render_image(&scene, settings(Method::Bdpt), None, spp, 44);
    assert_agree("caustic, bdpt against nee", &mean_estimate(&bdpt_stats), &mean_estimate(&nee_stats));
    let nee_noise = relative_difference(&nee, &nee_again);
    let bdpt_noise = relative_difference(&bdpt, &bdpt_again);
    eprintln!("caustic: nee noise {nee_noise:.3e}, bdpt noise {bdpt_noise:.3e}");
    assert!(bdpt_noise < 0.25 * nee_noise, "bdpt {bdpt_noise:.3e} against nee {nee_noise:.3e}");
}

#[test]
fn bdpt_refuses_what_it_cannot_render() {
    let window = repository_scene("window", 16, 16);
    let lights = reference_tracer::session::LightRequest::new(None, None, false);
    let choice = reference_tracer::scene_intersector::IntersectorChoice::default();
    let mut session = reference_tracer::session::prepare_with_lights(&window, choice, None, lights).unwrap();
    let render = support::render_settings(settings(Method::Bdpt), 1, 1, Schedule::Online);
    let error = session.render(&render, |_| {}).unwrap_err();
    assert!(error.starts_with("bdpt:") && error.contains("environment"), "{error}");
}
