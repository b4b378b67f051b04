//! Triangle meshes from Wavefront OBJ (tobj) and PLY (ply-rs-bw) files.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::Vec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use super::error::SceneError;

/// Positions and triangle indices of a mesh file.
pub struct MeshData {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Three vertex indices per triangle (polygons fanned).
    pub triangles: Vec<[u32; 3]>,
}

/// Loads `path` by its extension (`.obj` or `.ply`); errors name `location`, the JSON
/// path of the shape that references the file, and the file itself.
pub fn load_mesh(path: &Path, scene_file: &Path, location: &str) -> Result<MeshData, SceneError> {
    let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let fail = |message: String| SceneError::new(scene_file, location, format!("{}: {message}", path.display()));
    let format = match extension.as_deref() {
        Some("obj") => MeshFormat::Obj,
        Some("ply") => MeshFormat::Ply,
        _ => return Err(fail("unsupported mesh format (expected .obj or .ply)".into())),
    };
    let file = File::open(path).map_err(|e| fail(format!("cannot open: {e}")))?;
    parse_mesh(format, &mut BufReader::new(file)).map_err(fail)
}

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (polygons are triangulated; MTL references are ignored).
    Obj,
    /// Stanford PLY, ASCII or binary (`vertex` x y z, `face` vertex_indices).
    Ply,
}

/// Reads a mesh from `reader` and checks it: every position finite, every index within
/// the vertices. Errors say what is wrong (without the file's name).
pub fn parse_mesh(format: MeshFormat, reader: &mut impl BufRead) -> Result<MeshData, String> {
    let mesh = match format {
        MeshFormat::Obj => parse_obj(reader)?,
        MeshFormat::Ply => parse_ply(reader)?,
    };
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i} has a NaN or infinite coordinate"));
    }
    let count = mesh.positions.len() as u32;
    if let Some(t) = mesh.triangles.iter().position(|t| t.iter().any(|&i| i >= count)) {
        return Err(format!("face {t} refers to a vertex beyond the {count} vertices"));
    }
    Ok(mesh)
}

fn parse_obj(reader: &mut impl BufRead) -> Result<MeshData, String> {
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ..Default::default() };
    // Materials come from the scene file; the OBJ's own MTL references are ignored.
    let (models, _materials) = tobj::load_obj_buf(reader, &options, |_| Err(tobj::LoadError::OpenFileFailed))
        .map_err(|e| format!("cannot read OBJ: {e}"))?;
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for model in models {
        let offset = positions.len() as u32;
        positions.extend(model.mesh.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        triangles.extend(model.mesh.indices.chunks_exact(3).map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]));
    }
    Ok(MeshData { positions, triangles })
}

fn scalar(property: Option<&Property>) -> Option<f32> {
    Some(match property? {
        Property::Float(v) => *v,
        Property::Double(v) => *v as f32,
        Property::Int(v) => *v as f32,
        Property::UInt(v) => *v as f32,
        Property::Short(v) => *v as f32,
        Property::UShort(v) => *v as f32,
        Property::Char(v) => *v as f32,
        Property::UChar(v) => *v as f32,
        _ => return None,
    })
}

fn index_list(property: Option<&Property>) -> Option<Vec<u32>> {
    let to_u32 = |v: i64| u32::try_from(v).ok();
    match property? {
        Property::ListInt(v) => v.iter().map(|&i| to_u32(i as i64)).collect(),
        Property::ListUInt(v) => Some(v.clone()),
        Property::ListShort(v) => v.iter().map(|&i| to_u32(i as i64)).collect(),
        Property::ListUShort(v) => Some(v.iter().map(|&i| i as u32).collect()),
        Property::ListChar(v) => v.iter().map(|&i| to_u32(i as i64)).collect(),
        Property::ListUChar(v) => Some(v.iter().map(|&i| i as u32).collect()),
        _ => None,
    }
}

fn parse_ply(reader: &mut impl BufRead) -> Result<MeshData, String> {
    let ply = Parser::<DefaultElement>::new().read_ply(reader).map_err(|e| format!("cannot read PLY: {e}"))?;
    let vertices = ply.payload.get("vertex").ok_or("no `vertex` element")?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        match (scalar(v.get("x")), scalar(v.get("y")), scalar(v.get("z"))) {
            (Some(x), Some(y), Some(z)) => positions.push(Vec3::new(x, y, z)),
            _ => return Err(format!("vertex {i} lacks numeric x, y, z")),
        }
    }
    let mut triangles = Vec::new();
    for (i, face) in ply.payload.get("face").map(Vec::as_slice).unwrap_or_default().iter().enumerate() {
        let indices = index_list(face.get("vertex_indices").or_else(|| face.get("vertex_index")))
            .ok_or_else(|| format!("face {i} lacks a non-negative vertex_indices list"))?;
        // Fan polygons into triangles.
        for k in 1..indices.len().saturating_sub(1) {
            triangles.push([indices[0], indices[k], indices[k + 1]]);
        }
    }
    Ok(MeshData { positions, triangles })
}
