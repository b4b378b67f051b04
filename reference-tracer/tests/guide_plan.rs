//! The guide plan builds what a scene needs and nothing else: no light guide for a scene
//! with one lamp, or for a method without next-event estimation; a learned one for 64
//! lights; no directional guide for unguided methods; nothing for an absent environment.

mod support;

use std::path::Path;

use guiding_core::{EnvTileGuideSettings, HemisphereGridSettings, LightGuideSettings};
use reference_tracer::integrator::{EnvironmentSampling, LightSelection, Method};
use reference_tracer::scene_intersector::IntersectorChoice;
use reference_tracer::session::{prepare_with_lights, LightRequest};

fn plan(scene: &str, method: Method, selection: Option<LightSelection>) -> reference_tracer::session::Session {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(scene).join("scene.json");
    let guide = method.uses_guide().then(|| HemisphereGridSettings { budget_bytes: 64 << 10, ..Default::default() });
    let lights = LightRequest::new(selection, None, method.uses_nee());
    prepare_with_lights(&path, IntersectorChoice::default(), guide.map(Into::into), lights).unwrap()
}

#[test]
fn one_lamp_gets_power_selection_and_no_light_guide() {
    let session = plan("cornell", Method::Nee, None);
    assert_eq!(session.plan.light_selection, LightSelection::Power);
    assert!(session.learners.light_guide.is_none() && session.learners.guide.is_none());
    assert!(session.plan.describe().contains("environment: none"), "{}", session.plan.describe());
}

#[test]
fn sixty_four_lights_get_a_learned_light_guide() {
    let session = plan("many_lights", Method::Nee, None);
    assert_eq!(session.plan.light_selection, LightSelection::Learned);
    let guide = session.learners.light_guide.as_ref().expect("a light guide");
    assert_eq!(guide.light_count(), session.scene.lights.len());
    assert!(guide.memory_bytes() <= LightGuideSettings::default().budget_bytes + 64 * 1024);
}

#[test]
fn methods_without_next_event_estimation_build_no_light_guide() {
    for method in [Method::Pt, Method::Guided] {
        let session = plan("many_lights", method, None);
        assert!(session.learners.light_guide.is_none(), "{method:?}");
        assert_eq!(session.learners.guide.is_some(), method.uses_guide());
    }
    // Asked for explicitly, it is still not built where nothing would use it.
    assert!(plan("many_lights", Method::Pt, Some(LightSelection::Learned)).learners.light_guide.is_none());
}

#[test]
fn an_explicit_choice_overrides_the_plan() {
    let session = plan("many_lights", Method::Nee, Some(LightSelection::Uniform));
    assert_eq!(session.plan.light_selection, LightSelection::Uniform);
    assert!(session.learners.light_guide.is_none());
    let session = plan("window", Method::GuidedNee, None);
    assert!(
        session.plan.describe().contains("environment: learned tiles and a separate sun"),
        "{}",
        session.plan.describe()
    );
    assert!(session.learners.guide.is_some());
}

#[test]
fn an_environment_guide_is_built_only_where_an_environment_meets_next_event_estimation() {
    // No environment: nothing allocated for it, whatever the method.
    for method in Method::ALL {
        let session = plan("cornell", method, None);
        assert!(session.learners.environment_guide.is_none(), "{method:?}");
        assert_eq!(session.plan.environment_sampling, EnvironmentSampling::Luminance);
    }
    // An environment: tiles for next-event estimation, with the sun as its own lobe.
    let session = plan("window", Method::Nee, None);
    let guide = session.learners.environment_guide.as_ref().expect("an environment guide");
    assert!(guide.sun().is_some() && guide.lobe_count() == guide.tiles().tile_count() + 1);
    assert!(guide.table_bytes() <= EnvTileGuideSettings::default().budget_bytes);
    // Methods that never sample the environment directly build none.
    for method in [Method::Pt, Method::Guided] {
        assert!(plan("window", method, None).learners.environment_guide.is_none(), "{method:?}");
    }
    // Asked for plain luminance sampling: none.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/window/scene.json");
    let request = LightRequest::new(None, Some(EnvironmentSampling::Luminance), true);
    let session = prepare_with_lights(&path, IntersectorChoice::default(), None, request).unwrap();
    assert!(session.learners.environment_guide.is_none());
}

#[test]
fn a_scene_of_mirrors_and_glass_gets_no_directional_guide() {
    let folder = support::temp_folder("plan-mirrors");
    let scene = serde_json::json!({
        "format": 1,
        "camera": { "eye": [0, 1, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y_deg": 40, "width": 8, "height": 8 },
        "materials": {
            "mirror": { "type": "conductor", "specular": [0.9, 0.9, 0.9], "alpha": 0 },
            "glass": { "type": "dielectric", "ior": 1.5 }
        },
        "shapes": [
            { "type": "quad", "material": "mirror", "corners": [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]] },
            { "type": "quad", "material": "glass", "corners": [[-1, 1, 1], [1, 1, 1], [1, 1, -1], [-1, 1, -1]] }
        ],
        "environment": { "type": "constant", "radiance": [1, 1, 1] }
    });
    let path = support::write_scene(&folder, &scene);
    let guide = Some(HemisphereGridSettings { budget_bytes: 64 << 10, ..Default::default() });
    let session = prepare_with_lights(
        &path,
        IntersectorChoice::default(),
        guide.map(Into::into),
        LightRequest::new(None, None, true),
    )
    .unwrap();
    assert!(!session.plan.directions && session.learners.guide.is_none(), "{}", session.plan.describe());
    assert!(session.plan.describe().contains("0 diffuse, 0 glossy, 4 delta triangles"), "{}", session.plan.describe());
    // It still renders (BSDF and environment sampling only).
    let settings = reference_tracer::render::RenderSettings {
        integrator: reference_tracer::integrator::IntegratorSettings {
            method: Method::GuidedNee,
            ..Default::default()
        },
        budget: reference_tracer::render::Budget::SamplesPerPixel(2),
        seed: 1,
        train_seconds: 0.0,
        schedule: reference_tracer::schedule::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    let mut session = session;
    let (image, _) = session.render(&settings, |_| {}).unwrap();
    assert!(image.pixels.iter().all(|p| p.is_finite()) && image.mean().max_element() > 0.0);
}
