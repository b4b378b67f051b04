//! Any bytes as a mesh file (first byte even: OBJ, odd: PLY, ASCII or binary): a mesh
//! with finite positions and in-range indices, or an error; never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use reference_tracer::scene::{parse_mesh, MeshFormat};

fuzz_target!(|data: &[u8]| {
    let Some((&selector, file)) = data.split_first() else { return };
    let format = if selector % 2 == 0 { MeshFormat::Obj } else { MeshFormat::Ply };
    if let Ok(mesh) = parse_mesh(format, &mut &file[..]) {
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
        assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < mesh.positions.len()));
    }
});
