//! Any bytes as a scene file: loading either builds a scene whose every number is
//! finite, or fails with an error naming the file; it never panics.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use reference_tracer::scene::Scene;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    // Relative mesh and image names resolve against the repository's scenes folder, so
    // inputs seeded from real scenes reach the mesh and environment loaders.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.json");
    match Scene::from_json(&path, text) {
        Ok(scene) => {
            assert!(scene.triangles.iter().all(|t| t.vertices.iter().all(|v| v.is_finite())));
            assert!(scene.normals.iter().all(|n| n.is_finite()));
            assert_eq!(scene.triangles.len(), scene.triangle_materials.len());
        }
        Err(error) => assert!(error.to_string().contains("scene.json"), "{error}"),
    }
});
