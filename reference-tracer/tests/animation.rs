//! Instant radiosity (`--integrator vpl`) and animations (`--frames N`): vpl estimates
//! cornell's image as nee does, to the bias of its clamp, and vpl-guided (its light
//! subpaths guided by a learned W) as vpl does; and over 16 frames of a static
//! scene seen by a moving camera, frames rendered coherently (the same random numbers,
//! the learners carried over) differ less from one to the next in a fixed region than
//! frames rendered as separate renders.

mod support;

use guiding_core::{HemisphereGridSettings, SpatialDirectionalTreeSettings};
use reference_tracer::animation::frame_seed;
use reference_tracer::integrator::Method;
use reference_tracer::output::Image;
use reference_tracer::scene_intersector::IntersectorChoice;
use reference_tracer::session::{prepare_with_lights, LightRequest};
use support::{assert_agree, mean_estimate, render_image, render_scheduled, render_settings, settings, Schedule};

/// Cornell at 24×24, its camera moving 0.3 to the right over the animation (the box is
/// 2 wide), still looking at its centre.
fn moving_cornell() -> std::path::PathBuf {
    let path = support::repository_scene("cornell", 24, 24);
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    json["camera"]["keyframes"] = serde_json::json!([
        { "eye": [0.0, 1.0, 3.9], "target": [0.0, 1.0, 0.0] },
        { "eye": [0.3, 1.0, 3.9], "target": [0.0, 1.0, 0.0] }
    ]);
    std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    path
}

/// The mean over the 8×8 pixels at the image's centre of |a − b| (channels averaged),
/// relative to their mean there.
fn centre_difference(a: &Image, b: &Image) -> f64 {
    let (mut difference, mut mean) = (0.0f64, 0.0f64);
    for y in 8..16 {
        for x in 8..16 {
            let (p, q) = (a.pixels[y * a.width + x], b.pixels[y * b.width + x]);
            for c in 0..3 {
                difference += (p[c] - q[c]).abs() as f64;
                mean += 0.5 * (p[c] + q[c]) as f64;
            }
        }
    }
    difference / mean.max(1e-12)
}

/// The 16 frames of the moving cornell by vpl at 2 spp each, coherent or not.
fn frames(coherent: bool) -> Vec<Image> {
    let scene = moving_cornell();
    let request = LightRequest::new(None, None, false);
    let prepare = || prepare_with_lights(&scene, IntersectorChoice::default(), None, request).unwrap();
    let mut session = prepare();
    assert_eq!(session.scene.camera_keyframes.len(), 2);
    let mut images = Vec::new();
    for frame in 0..16 {
        if frame > 0 && !coherent {
            session = prepare();
        }
        session.scene.camera = session.scene.frame_camera(frame, 16);
        let render = render_settings(settings(Method::Vpl), 2, frame_seed(5, frame, coherent), Schedule::Online);
        images.push(session.render(&render, |_| {}).unwrap().0);
    }
    images
}

#[test]
fn coherent_frames_flicker_less_than_separate_ones() {
    let mean_step = |images: &[Image]| {
        images.windows(2).map(|pair| centre_difference(&pair[0], &pair[1])).sum::<f64>() / (images.len() - 1) as f64
    };
    let coherent = mean_step(&frames(true));
    let separate = mean_step(&frames(false));
    eprintln!("mean frame-to-frame difference at the centre: coherent {coherent:.4}, separate {separate:.4}");
    assert!(coherent < 0.5 * separate, "coherent {coherent:.4} against separate {separate:.4}");
}

#[test]
fn vpl_estimates_cornell_as_nee_does_to_its_clamp() {
    let scene = support::repository_scene("cornell", 24, 24);
    let (_, nee) = render_image(&scene, settings(Method::Nee), None, 256, 3);
    let (_, vpl) = render_image(&scene, settings(Method::Vpl), None, 64, 4);
    let (nee, vpl) = (mean_estimate(&nee), mean_estimate(&vpl));
    // The clamp darkens light exchanged within 2 % of the scene's extent (the corners):
    // a per cent or so of the image's mean.
    let difference = (vpl.mean - nee.mean) / nee.mean;
    assert!(difference.abs() < 0.03, "vpl {} against nee {} ({difference:+.4})", vpl.mean, nee.mean);
}

#[test]
fn vpl_guided_estimates_what_vpl_does() {
    let scene = support::repository_scene("cornell", 16, 16);
    let (_, vpl) = render_image(&scene, settings(Method::Vpl), None, 400, 5);
    let guided =
        reference_tracer::integrator::IntegratorSettings { guide_probability: 0.5, ..settings(Method::VplGuided) };
    for (label, guide) in
        [("grid", HemisphereGridSettings::default().into()), ("tree", SpatialDirectionalTreeSettings::default().into())]
    {
        let (_, learned) = render_scheduled(&scene, guided, Some(guide), 400, 6, Schedule::Iterative);
        assert!(learned.training_passes > 0, "{label}: W trained");
        assert_agree(&format!("vpl-guided {label} against vpl"), &mean_estimate(&learned), &mean_estimate(&vpl));
    }
}
