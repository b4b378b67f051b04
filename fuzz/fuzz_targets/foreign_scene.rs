//! Any bytes as a pbrt-v3 (first byte even) or Mitsuba XML (odd) scene: reading and
//! building it either gives a scene whose every number is finite or an error naming the
//! file; it never panics.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use reference_tracer::import::{mitsuba, pbrt};
use reference_tracer::scene::Scene;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, rest)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(rest) else { return };
    // Relative file names resolve beside the original Cornell box's small OBJ and MTL.
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box-original");
    let (path, imported) = if selector % 2 == 0 {
        let path = folder.join("fuzz.pbrt");
        let imported = pbrt::read(&path, text);
        (path, imported)
    } else {
        let path = folder.join("fuzz.xml");
        let imported = mitsuba::read(&path, text);
        (path, imported)
    };
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    match imported.and_then(|imported| Scene::from_description(&path, imported.description)) {
        Ok(scene) => {
            assert!(scene.triangles.iter().all(|t| t.vertices.iter().all(|v| v.is_finite())));
            assert!(scene.vertex_normals.iter().flatten().all(|n| n.is_finite()));
            assert_eq!(scene.triangles.len(), scene.triangle_materials.len());
        }
        Err(error) => assert!(error.to_string().contains(&name), "{error}"),
    }
});
