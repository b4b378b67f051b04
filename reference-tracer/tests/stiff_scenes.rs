//! Stiff and extreme scenes: radiance spanning twelve orders of magnitude, a tiny sun disk of 1e9, a dim
//! emitter, a tiny light, grazing camera rays, broken triangles, and the whole scene
//! moved far from the origin or scaled. Each render must be finite and match the known
//! answer, or the unmodified scene, within noise (4 standard errors from pass means).

mod support;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use glam::Vec3;
use guiding_core::HemisphereGridSettings;
use reference_tracer::directional_guide::DirectionalGuideSettings;
use reference_tracer::integrator::{EnvironmentSampling, IntegratorSettings, Method};
use reference_tracer::output::{write_pfm, Image};
use reference_tracer::scene::Scene;
use serde_json::{json, Value};
use support::{assert_agree, mean_estimate, render_image, render_scene, settings, MeanEstimate};

fn guide_settings() -> Option<DirectionalGuideSettings> {
    Some(HemisphereGridSettings { budget_bytes: 256 << 10, ..Default::default() }.into())
}

fn estimate(scene: &Path, method: Method, spp: u32, seed: u64) -> MeanEstimate {
    let statistics = render_scene(scene, settings(method), guide_settings(), spp, seed);
    assert!(statistics.pass_means.iter().flatten().all(|v| v.is_finite()), "{method:?}: non-finite pass mean");
    mean_estimate(&statistics)
}

/// The repository's Cornell box at 24 × 24 pixels, edited, in a folder of its own.
fn cornell(name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
    let mut json: Value = serde_json::from_str(&std::fs::read_to_string(source.join("scene.json")).unwrap()).unwrap();
    json["camera"]["width"] = json!(24);
    json["camera"]["height"] = json!(24);
    edit(&mut json);
    let folder = support::temp_folder(&format!("stiff-{name}"));
    std::fs::create_dir_all(folder.join("meshes")).unwrap();
    for mesh in ["short_box.obj", "tall_box.obj"] {
        std::fs::copy(source.join("meshes").join(mesh), folder.join("meshes").join(mesh)).unwrap();
    }
    support::write_scene(&folder, &json)
}

/// A large diffuse floor of albedo 0.5 at y = 0 seen from straight above, under `environment`.
fn floor_scene(name: &str, environment: Value) -> PathBuf {
    let folder = support::temp_folder(name);
    let scene = json!({
        "format": 1,
        "camera": { "eye": [0, 1, 0], "target": [0, 0, 0], "up": [0, 0, -1], "fov_y_deg": 60, "width": 12, "height": 12 },
        "materials": { "floor": { "type": "diffuse", "albedo": [0.5, 0.5, 0.5] } },
        "shapes": [{ "type": "quad", "material": "floor",
                     "corners": [[-100, 0, -100], [-100, 0, 100], [100, 0, 100], [100, 0, -100]] }],
        "environment": environment
    });
    support::write_scene(&folder, &scene)
}

#[test]
fn a_sun_of_1e6_over_a_sky_of_1e_minus_3() {
    // A 64 × 32 lat-long map: sky 1e-3 everywhere, one texel of 1e6 at row 5 (above the
    // horizon). Texels are piecewise constant, so the floor's radiance is exactly
    // ρ/π · Σ L_t ∫_t cos θ dω with ∫_t cos θ dω = Δφ (sin²θ₁ − sin²θ₀)/2.
    let (width, height, sun_row, sun_column) = (64usize, 32usize, 5usize, 20usize);
    let mut pixels = vec![Vec3::splat(1e-3); width * height];
    pixels[sun_row * width + sun_column] = Vec3::splat(1e6);
    let folder = support::temp_folder("stiff-sun");
    write_pfm(&folder.join("sun.pfm"), &Image { width, height, pixels: pixels.clone() }).unwrap();
    let irradiance: f64 = (0..height / 2)
        .flat_map(|row| (0..width).map(move |column| (row, column)))
        .map(|(row, column)| {
            let (theta0, theta1) = (PI * row as f64 / height as f64, PI * (row + 1) as f64 / height as f64);
            let cosine_solid_angle = 2.0 * PI / width as f64 * (theta1.sin().powi(2) - theta0.sin().powi(2)) / 2.0;
            pixels[row * width + column].x as f64 * cosine_solid_angle
        })
        .sum();
    let expected = 0.5 / PI * irradiance;
    let scene = floor_scene("stiff-sun-scene", json!({ "type": "image", "file": "sun.pfm" }));
    std::fs::copy(folder.join("sun.pfm"), scene.parent().unwrap().join("sun.pfm")).unwrap();
    for method in [Method::Nee, Method::GuidedNee] {
        let e = estimate(&scene, method, 64, 1);
        assert!(
            (e.mean - expected).abs() <= 4.0 * e.standard_error + 1e-4 * expected,
            "{method:?}: {} ± {} vs exact {expected}",
            e.mean,
            e.standard_error
        );
    }
}

#[test]
fn a_sun_disk_of_1e9_and_a_twentieth_of_a_degree_over_a_sky_of_1e_minus_3() {
    // ∫ over a cone of half-angle r of ω dω = π sin²r · axis, so the floor's radiance is
    // exactly ρ/π · (π L_sky + L_sun π sin²r cos θ_sun).
    let (radius_deg, sun_radiance, sky) = (0.05f64, 1e9f64, 1e-3f64);
    let axis = Vec3::new(0.3, 0.6, -0.2).normalize();
    let environment = json!({ "type": "constant", "radiance": [sky, sky, sky],
        "sun": { "direction": [0.3, 0.6, -0.2], "angular_radius_deg": radius_deg, "radiance": [sun_radiance, sun_radiance, sun_radiance] } });
    let scene = floor_scene("stiff-sun-disk", environment);
    let r = radius_deg.to_radians();
    let expected = 0.5 / PI * (PI * sky + sun_radiance * PI * r.sin().powi(2) * axis.y as f64);
    for (i, (method, sampling)) in [
        (Method::Nee, EnvironmentSampling::Luminance),
        (Method::Nee, EnvironmentSampling::Tiles),
        (Method::GuidedNee, EnvironmentSampling::Tiles),
    ]
    .into_iter()
    .enumerate()
    {
        let integrator = IntegratorSettings { environment_sampling: sampling, ..settings(method) };
        let statistics = render_scene(&scene, integrator, guide_settings(), 64, 3 + i as u64);
        assert!(statistics.pass_means.iter().flatten().all(|v| v.is_finite()), "{method:?} {sampling:?}");
        let e = mean_estimate(&statistics);
        assert!(
            (e.mean - expected).abs() <= 4.0 * e.standard_error + 1e-3 * expected,
            "{method:?} {sampling:?}: {} ± {} vs exact {expected}",
            e.mean,
            e.standard_error
        );
    }
}

#[test]
fn an_emitter_of_1e_minus_6_scales_the_image_linearly() {
    let bright = cornell("bright", |_| {});
    let dim = cornell("dim", |j| j["materials"]["lamp"]["emission"] = json!([17e-6, 12e-6, 4e-6]));
    // Same seed, same paths: nee's image scales exactly (up to rounding).
    let (b, d) = (estimate(&bright, Method::Nee, 32, 5), estimate(&dim, Method::Nee, 32, 5));
    assert!(d.mean > 0.0 && (d.mean / b.mean / 1e-6 - 1.0).abs() < 1e-4, "{} / {}", d.mean, b.mean);
    // Guided learning sees targets a million times smaller than its initial Q and still
    // agrees with nee.
    let guided = estimate(&dim, Method::GuidedNee, 64, 6);
    let reference = estimate(&dim, Method::Nee, 64, 7);
    assert_agree("dim guided-nee vs nee", &guided, &reference);
}

#[test]
fn a_light_of_one_millionth_of_the_scene_area() {
    // Cornell's walls and boxes have about 24 m² of area: a 5 mm square lamp has 2.5e-5 m²,
    // with its radiance raised so it emits the original lamp's power.
    let tiny = cornell("tiny-light", |j| {
        let lamp = j["shapes"].as_array_mut().unwrap().last_mut().unwrap();
        lamp["corners"] =
            json!([[-0.0025, 1.98, 0.0025], [-0.0025, 1.98, -0.0025], [0.0025, 1.98, -0.0025], [0.0025, 1.98, 0.0025]]);
        let scale = 0.47 * 0.38 / (0.005 * 0.005);
        j["materials"]["lamp"]["emission"] = json!([17.0 * scale, 12.0 * scale, 4.0 * scale]);
    });
    let nee = estimate(&tiny, Method::Nee, 64, 11);
    let guided = estimate(&tiny, Method::GuidedNee, 64, 12);
    assert!(nee.mean > 0.0);
    assert_agree("tiny light guided-nee vs nee", &guided, &nee);
}

#[test]
fn grazing_camera_rays_see_the_exact_floor_radiance() {
    // The camera sits 1e-6 above the floor with a vertical field of view of 1e-4 degrees
    // over 8 rows: rays below the horizon hit the floor at cos θ < 1e-6. Under a constant
    // sky of 1 a floor of albedo 0.5 reflects exactly 0.5, and pt estimates it with zero
    // variance (cosine sampling, every bounce escapes), so pixels must be exactly 1 above
    // the horizon and 0.5 in the rows below the one at the horizon (whose flattest rays
    // pass the floor's far edge): any ray that re-hit the floor it left would show.
    let scene = floor_scene("stiff-grazing", json!({ "type": "constant", "radiance": [1, 1, 1] }));
    let mut json: Value = serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    json["camera"] = json!({ "eye": [0, 1e-6, 0], "target": [0, 1e-6, -1], "up": [0, 1, 0],
                             "fov_y_deg": 1e-4, "width": 8, "height": 8 });
    let scene = support::write_scene(scene.parent().unwrap(), &json);
    let (image, _) = render_image(&scene, settings(Method::Pt), None, 8, 2);
    for (i, p) in image.pixels.iter().enumerate() {
        let row = i / image.width;
        let expected = match row {
            0..4 => 1.0..=1.0,
            4 => 0.5..=1.0,
            _ => 0.5..=0.5,
        };
        assert!(p.is_finite() && (expected.start() - 1e-4..=expected.end() + 1e-4).contains(&p.x), "pixel {i}: {p}");
    }
    let pt = estimate(&scene, Method::Pt, 64, 3);
    for method in [Method::Nee, Method::GuidedNee] {
        assert_agree(&format!("grazing {method:?} vs pt"), &estimate(&scene, method, 64, 4), &pt);
    }
}

#[test]
fn zero_area_flipped_and_zero_normal_triangles_in_a_mesh() {
    let broken = cornell("broken-mesh", |j| {
        j["shapes"].as_array_mut().unwrap().push(json!({ "type": "mesh", "file": "broken.obj", "material": "white" }));
        // The lamp wound the wrong way emits into the ceiling; a second, correct one lights the room.
        let mut flipped = j["shapes"].as_array().unwrap().last().cloned().unwrap();
        flipped["type"] = json!("quad");
        j["shapes"].as_array_mut().unwrap().push(json!({ "type": "quad", "material": "lamp",
            "corners": [[-0.1, 1.97, -0.1], [0.1, 1.97, -0.1], [0.1, 1.97, 0.1], [-0.1, 1.97, 0.1]] }));
    });
    // Zero-length and flipped vertex normals (ignored: geometry comes from the winding),
    // a zero-area face, a clockwise face and a sliver.
    std::fs::write(
        broken.parent().unwrap().join("broken.obj"),
        "v -0.5 0.5 -0.5\nv 0.5 0.5 -0.5\nv 0 0.9 -0.5\nv 0.25 0.5 -0.5\nv 0.2 0.5000001 -0.5\n\
         vn 0 0 0\nvn 0 0 1\nvn 0 0 -1\n\
         f 1//1 2//1 3//1\nf 1//2 4//2 2//2\nf 3//3 2//3 1//3\nf 1 5 2\n",
    )
    .unwrap();
    let scene = Scene::load(&broken).expect("broken triangles are dropped or kept, not fatal");
    assert!(scene.warnings.iter().any(|w| w.contains("degenerate")), "{:?}", scene.warnings);
    let nee = estimate(&broken, Method::Nee, 32, 4);
    let guided = estimate(&broken, Method::GuidedNee, 32, 5);
    assert!(nee.mean > 0.0);
    assert_agree("broken mesh guided-nee vs nee", &guided, &nee);
}

/// `p ↦ offset + scale·p` applied to every position of a cornell scene.
fn transformed_cornell(scale: f64, offset: f64) -> PathBuf {
    let map = |p: &Value| {
        json!(p.as_array().unwrap().iter().map(|c| offset + scale * c.as_f64().unwrap()).collect::<Vec<_>>())
    };
    cornell(&format!("moved-{scale}-{offset}"), |j| {
        for key in ["eye", "target"] {
            j["camera"][key] = map(&j["camera"][key]);
        }
        for shape in j["shapes"].as_array_mut().unwrap() {
            if let Some(corners) = shape.get_mut("corners") {
                *corners = json!(corners.as_array().unwrap().iter().map(map).collect::<Vec<_>>());
            } else {
                shape["transform"] =
                    json!([[scale, 0, 0, offset], [0, scale, 0, offset], [0, 0, scale, offset], [0, 0, 0, 1]]);
            }
        }
    })
}

#[test]
fn the_scene_moved_to_1e5_or_scaled_by_1e_minus_4_or_1e4_renders_the_same() {
    // (Scaling by 1e-4 at an offset of 1e5 is left out: the scene would be smaller than
    // one f32 step there.)
    let original = transformed_cornell(1.0, 0.0);
    for method in [Method::Nee, Method::GuidedNee] {
        let reference = estimate(&original, method, 128, 21);
        for (scale, offset) in [(1.0, 1e5), (1e-4, 0.0), (1e4, 0.0), (1e4, 1e5)] {
            let moved = estimate(&transformed_cornell(scale, offset), method, 128, 22);
            assert_agree(&format!("{method:?} scale {scale} offset {offset}"), &moved, &reference);
        }
    }
}

#[test]
fn nan_and_infinite_environment_texels_are_rejected_with_their_position() {
    for (name, bad) in [("nan", f32::NAN), ("inf", f32::INFINITY), ("negative", -1.0)] {
        let mut pixels = vec![Vec3::splat(0.5); 8 * 4];
        pixels[2 * 8 + 5] = Vec3::new(0.5, bad, 0.5);
        let scene = floor_scene(&format!("stiff-texel-{name}"), json!({ "type": "image", "file": "sky.pfm" }));
        write_pfm(&scene.parent().unwrap().join("sky.pfm"), &Image { width: 8, height: 4, pixels }).unwrap();
        let message = Scene::load(&scene).err().expect("the texel is rejected").to_string();
        assert!(message.contains("environment.file") && message.contains("texel (5, 2)"), "{name}: {message}");
    }
}
