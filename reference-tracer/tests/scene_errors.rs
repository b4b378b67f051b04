//! Every error case of SCENE_FORMAT.md is reported with the file and the JSON path, and
//! the command exits non-zero without panicking.

mod support;

use std::path::Path;

use reference_tracer::scene::Scene;
use serde_json::json;

fn base_scene() -> serde_json::Value {
    json!({
        "format": 1,
        "camera": { "eye": [0, 1, 3], "target": [0, 1, 0], "up": [0, 1, 0], "fov_y_deg": 40, "width": 8, "height": 8 },
        "materials": {
            "white": { "type": "diffuse", "albedo": [0.5, 0.5, 0.5] },
            "lamp": { "type": "diffuse", "albedo": [0.5, 0.5, 0.5], "emission": [4, 4, 4] }
        },
        "shapes": [
            { "type": "quad", "material": "white", "corners": [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]] },
            { "type": "triangles", "material": "lamp", "positions": [[0, 2, 0], [1, 2, 0], [0, 2, 1]], "indices": [0, 2, 1] }
        ]
    })
}

/// Loads `json` (after `edit`) and returns the error text, which must name the scene file.
fn error_of(name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let folder = support::temp_folder(&format!("errors-{name}"));
    let mut json = base_scene();
    edit(&mut json);
    let path = support::write_scene(&folder, &json);
    let error = Scene::load(&path).err().unwrap_or_else(|| panic!("{name}: the scene must be rejected"));
    let text = error.to_string();
    assert!(text.contains("scene.json"), "{name}: `{text}` does not name the file");
    text
}

fn assert_mentions(text: &str, parts: &[&str]) {
    for part in parts {
        assert!(text.contains(part), "`{text}` should mention `{part}`");
    }
}

#[test]
fn the_base_scene_loads() {
    let folder = support::temp_folder("errors-base");
    let path = support::write_scene(&folder, &base_scene());
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.triangles.len(), 3);
    assert_eq!(scene.lights.len(), 1);
}

#[test]
fn unknown_keys_name_their_path() {
    let text = error_of("unknown-key", |j| j["materials"]["white"]["albdo"] = json!([1, 1, 1]));
    assert_mentions(&text, &["materials.white", "albdo"]);
    let text = error_of("unknown-top", |j| j["lights"] = json!([]));
    assert_mentions(&text, &["lights"]);
    let text = error_of("unknown-type", |j| j["materials"]["white"]["type"] = json!("velvet"));
    assert_mentions(&text, &["materials.white", "velvet"]);
}

#[test]
fn missing_files_name_the_shape() {
    let text = error_of("missing-mesh", |j| {
        j["shapes"][0] = json!({ "type": "mesh", "file": "nowhere.obj", "material": "white" })
    });
    assert_mentions(&text, &["shapes[0].file", "nowhere.obj"]);
    let text = error_of("missing-env", |j| j["environment"] = json!({ "type": "image", "file": "sky.exr" }));
    assert_mentions(&text, &["environment.file", "sky.exr"]);
}

#[test]
fn unknown_material_names_are_errors() {
    let text = error_of("unknown-material", |j| j["shapes"][1]["material"] = json!("gold"));
    assert_mentions(&text, &["shapes[1].material", "gold"]);
}

#[test]
fn bad_radiance_is_an_error() {
    let text = error_of("negative-emission", |j| j["materials"]["lamp"]["emission"] = json!([-1, 0, 0]));
    assert_mentions(&text, &["materials.lamp.emission"]);
    // JSON has no NaN; a number beyond f32 becomes infinite and must be caught.
    let text = error_of("infinite-emission", |j| j["materials"]["lamp"]["emission"] = json!([1e39, 0, 0]));
    assert_mentions(&text, &["materials.lamp.emission"]);
    let text = error_of("negative-env", |j| j["environment"] = json!({ "type": "constant", "radiance": [0, -2, 0] }));
    assert_mentions(&text, &["environment.radiance"]);
    let text = error_of("albedo", |j| j["materials"]["white"]["albedo"] = json!([1.5, 0, 0]));
    assert_mentions(&text, &["materials.white.albedo"]);
}

#[test]
fn bad_suns_are_errors_naming_the_field() {
    let sun = |field: &str, value: serde_json::Value| {
        let mut sun = json!({ "direction": [0, 1, 0], "angular_radius_deg": 0.5, "radiance": [1000, 1000, 1000] });
        sun[field] = value;
        move |j: &mut serde_json::Value| {
            j["environment"] = json!({ "type": "constant", "radiance": [0.1, 0.1, 0.1], "sun": sun })
        }
    };
    for (name, field, value, path) in [
        ("sun-zero-direction", "direction", json!([0, 0, 0]), "environment.sun.direction"),
        ("sun-zero-radius", "angular_radius_deg", json!(0), "environment.sun.angular_radius_deg"),
        ("sun-huge-radius", "angular_radius_deg", json!(120), "environment.sun.angular_radius_deg"),
        ("sun-negative", "radiance", json!([-1, 0, 0]), "environment.sun.radiance"),
        ("sun-infinite", "radiance", json!([1e39, 0, 0]), "environment.sun.radiance"),
    ] {
        assert_mentions(&error_of(name, sun(field, value)), &[path]);
    }
    let text = error_of("sun-unknown-key", |j| {
        j["environment"] = json!({ "type": "constant", "radiance": [0.1, 0.1, 0.1],
            "sun": { "direction": [0, 1, 0], "angular_radius_deg": 0.5, "radiance": [1, 1, 1], "size": 2 } })
    });
    assert_mentions(&text, &["environment", "size"]);
}

#[test]
fn index_out_of_range_and_bad_counts() {
    let text = error_of("index", |j| j["shapes"][1]["indices"] = json!([0, 1, 7]));
    assert_mentions(&text, &["shapes[1].indices[2]", "out of range"]);
    let text = error_of("count", |j| j["shapes"][1]["indices"] = json!([0, 1]));
    assert_mentions(&text, &["shapes[1].indices", "multiple of 3"]);
}

#[test]
fn degenerate_triangles_are_dropped_with_a_warning_or_rejected_when_nothing_is_left() {
    let folder = support::temp_folder("errors-degenerate");
    let mut json = base_scene();
    json["shapes"][1]["positions"] = json!([[0, 2, 0], [1, 2, 0], [2, 2, 0], [0, 2, 1]]);
    json["shapes"][1]["indices"] = json!([0, 1, 2, 0, 3, 1]);
    let scene = Scene::load(&support::write_scene(&folder, &json)).unwrap();
    assert!(scene.warnings.iter().any(|w| w.contains("1 degenerate")), "{:?}", scene.warnings);
    let text = error_of(
        "all-degenerate",
        |j| j["shapes"] = json!([{ "type": "triangles", "material": "white", "positions": [[0, 0, 0], [1, 0, 0], [2, 0, 0]], "indices": [0, 1, 2] }]),
    );
    assert_mentions(&text, &["shapes", "no triangle"]);
}

#[test]
fn camera_and_format_errors() {
    assert_mentions(&error_of("width", |j| j["camera"]["width"] = json!(0)), &["camera.width"]);
    assert_mentions(&error_of("fov", |j| j["camera"]["fov_y_deg"] = json!(180)), &["camera.fov_y_deg"]);
    assert_mentions(&error_of("view", |j| j["camera"]["target"] = json!([0, 1, 3])), &["camera.target"]);
    assert_mentions(&error_of("format", |j| j["format"] = json!(2)), &["format"]);
    assert_mentions(&error_of("type-mismatch", |j| j["camera"]["eye"] = json!("here")), &["camera.eye"]);
}

#[test]
fn broken_meshes_and_images_name_the_file() {
    let folder = support::temp_folder("errors-broken-files");
    std::fs::write(
        folder.join("broken.ply"),
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\nnot-a-number\n",
    )
    .unwrap();
    std::fs::write(folder.join("nan.obj"), b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(folder.join("empty.pfm"), b"PF\n0 0\n-1\n").unwrap();
    let cases = [
        (json!({ "type": "mesh", "file": "broken.ply", "material": "white" }), "broken.ply"),
        (json!({ "type": "mesh", "file": "nan.obj", "material": "white" }), "nan.obj"),
        (json!({ "type": "mesh", "file": "mesh.stl", "material": "white" }), "mesh.stl"),
    ];
    for (shape, file) in cases {
        let mut json = base_scene();
        json["shapes"][0] = shape;
        let text = Scene::load(&support::write_scene(&folder, &json)).err().unwrap().to_string();
        assert_mentions(&text, &["shapes[0].file", file]);
    }
    let mut json = base_scene();
    json["environment"] = json!({ "type": "image", "file": "empty.pfm" });
    let text = Scene::load(&support::write_scene(&folder, &json)).err().unwrap().to_string();
    assert_mentions(&text, &["environment.file", "empty.pfm"]);
}

#[test]
fn malformed_json_gives_line_and_column() {
    let folder = support::temp_folder("errors-json");
    let path = folder.join("scene.json");
    std::fs::write(&path, "{ \"format\": 1,\n  \"camera\": [ }").unwrap();
    let text = Scene::load(&path).err().unwrap().to_string();
    assert_mentions(&text, &["scene.json", "line 2"]);
    let text = Scene::load(Path::new("/nonexistent/scene.json")).err().unwrap().to_string();
    assert_mentions(&text, &["/nonexistent/scene.json", "cannot read"]);
}

#[test]
fn the_command_exits_non_zero_with_the_message() {
    let folder = support::temp_folder("errors-command");
    let mut json = base_scene();
    json["shapes"][1]["material"] = json!("gold");
    let path = support::write_scene(&folder, &json);
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_lodestar"))
        .args(["render", path.to_str().unwrap(), "--spp", "1", "--out", folder.join("x.exr").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("shapes[1].material") && stderr.contains("gold"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn bad_camera_keyframes_name_the_keyframe() {
    let text =
        error_of("one-keyframe", |j| j["camera"]["keyframes"] = json!([{ "eye": [0, 1, 3], "target": [0, 1, 0] }]));
    assert_mentions(&text, &["camera.keyframes[0]", "at least two"]);
    let text = error_of("keyframe-along-up", |j| {
        j["camera"]["keyframes"] =
            json!([{ "eye": [0, 1, 3], "target": [0, 1, 0] }, { "eye": [0, 1, 0], "target": [0, 3, 0] }])
    });
    assert_mentions(&text, &["camera.keyframes[1].target", "parallel"]);
    let text = error_of("keyframe-key", |j| {
        j["camera"]["keyframes"] =
            json!([{ "eye": [0, 1, 3], "target": [0, 1, 0] }, { "eye": [0, 1, 3], "taret": [0, 1, 0] }])
    });
    assert_mentions(&text, &["keyframes", "taret"]);
}
