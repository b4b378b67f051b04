//! Triangle meshes from Wavefront OBJ (tobj, with its MTL materials) and PLY
//! (ply-rs-bw) files: positions, optional per-vertex normals and texture coordinates.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::{Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use super::error::SceneError;

/// Positions and triangle indices of a mesh file, with what else it carries.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Three vertex indices per triangle (polygons fanned).
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex normals (not necessarily unit), parallel to `positions`, if every
    /// vertex has one.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates, parallel to `positions`, if every vertex has them.
    pub uvs: Option<Vec<Vec2>>,
    /// An OBJ's MTL materials, and the index into them of each triangle (`None` for
    /// faces without one).
    pub face_materials: Option<(Vec<MtlMaterial>, Vec<Option<u32>>)>,
}

/// The parts of an MTL material the tracer uses: a diffuse reflectance and an emission.
#[derive(Clone, Debug, PartialEq)]
pub struct MtlMaterial {
    /// `newmtl` name.
    pub name: String,
    /// `Kd`, default black.
    pub diffuse: [f32; 3],
    /// `Ke`, default black.
    pub emission: [f32; 3],
}

/// Loads `path` by its extension (`.obj` or `.ply`); errors name `location`, the JSON
/// path of the shape that references the file, and the file itself. An OBJ's MTL
/// libraries are read from beside it.
pub fn load_mesh(path: &Path, scene_file: &Path, location: &str) -> Result<MeshData, SceneError> {
    let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let fail = |message: String| SceneError::new(scene_file, location, format!("{}: {message}", path.display()));
    let format = match extension.as_deref() {
        Some("obj") => MeshFormat::Obj,
        Some("ply") => MeshFormat::Ply,
        _ => return Err(fail("unsupported mesh format (expected .obj or .ply)".into())),
    };
    let file = File::open(path).map_err(|e| fail(format!("cannot open: {e}")))?;
    let folder = path.parent().unwrap_or(Path::new("."));
    let mesh = match format {
        MeshFormat::Obj => parse_obj(&mut BufReader::new(file), &|mtl: &Path| {
            let file = File::open(folder.join(mtl)).map_err(|_| tobj::LoadError::OpenFileFailed)?;
            tobj::load_mtl_buf(&mut BufReader::new(file))
        }),
        MeshFormat::Ply => parse_ply(&mut BufReader::new(file)),
    };
    mesh.and_then(check_mesh).map_err(fail)
}

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (polygons are triangulated; MTL references are ignored).
    Obj,
    /// Stanford PLY, ASCII or binary (`vertex` x y z, `face` vertex_indices).
    Ply,
}

/// Reads a mesh from `reader` (an OBJ's MTL libraries are not read) and checks it:
/// every position, normal and texture coordinate finite, every index within the
/// vertices. Errors say what is wrong (without the file's name).
pub fn parse_mesh(format: MeshFormat, reader: &mut impl BufRead) -> Result<MeshData, String> {
    let mesh = match format {
        MeshFormat::Obj => parse_obj(reader, &|_: &Path| Err(tobj::LoadError::OpenFileFailed))?,
        MeshFormat::Ply => parse_ply(reader)?,
    };
    check_mesh(mesh)
}

fn check_mesh(mesh: MeshData) -> Result<MeshData, String> {
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i} has a NaN or infinite coordinate"));
    }
    if let Some(i) = mesh.normals.iter().flatten().position(|n| !n.is_finite()) {
        return Err(format!("vertex {i} has a NaN or infinite normal"));
    }
    if let Some(i) = mesh.uvs.iter().flatten().position(|uv| !uv.is_finite()) {
        return Err(format!("vertex {i} has a NaN or infinite texture coordinate"));
    }
    let count = mesh.positions.len() as u32;
    if let Some(t) = mesh.triangles.iter().position(|t| t.iter().any(|&i| i >= count)) {
        return Err(format!("face {t} refers to a vertex beyond the {count} vertices"));
    }
    Ok(mesh)
}

fn parse_obj(reader: &mut impl BufRead, mtl_loader: &dyn Fn(&Path) -> tobj::MTLLoadResult) -> Result<MeshData, String> {
    // One index per vertex, so normals and texture coordinates line up with positions.
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, materials) =
        tobj::load_obj_buf(reader, &options, mtl_loader).map_err(|e| format!("cannot read OBJ: {e}"))?;
    // A missing MTL library leaves the faces without materials; the scene then names one.
    let materials = materials.unwrap_or_default();
    let mut mesh = MeshData::default();
    let (mut normals, mut uvs) = (Vec::new(), Vec::new());
    let (mut all_normals, mut all_uvs) = (true, true);
    let mut face_materials = Vec::new();
    for model in models {
        let m = &model.mesh;
        let offset = mesh.positions.len() as u32;
        let vertices = m.positions.len() / 3;
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        all_normals &= m.normals.len() == 3 * vertices;
        all_uvs &= m.texcoords.len() == 2 * vertices;
        normals.extend(m.normals.chunks_exact(3).map(|n| Vec3::new(n[0], n[1], n[2])));
        uvs.extend(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])));
        let material = m.material_id.filter(|&id| id < materials.len()).map(|id| id as u32);
        for t in m.indices.chunks_exact(3) {
            mesh.triangles.push([t[0] + offset, t[1] + offset, t[2] + offset]);
            face_materials.push(material);
        }
    }
    mesh.normals = (all_normals && !normals.is_empty()).then_some(normals);
    mesh.uvs = (all_uvs && !uvs.is_empty()).then_some(uvs);
    if !materials.is_empty() {
        let known = materials
            .iter()
            .map(|m| MtlMaterial {
                name: m.name.clone(),
                diffuse: m.diffuse.unwrap_or([0.0; 3]),
                emission: m.emissive.unwrap_or([0.0; 3]),
            })
            .collect();
        mesh.face_materials = Some((known, face_materials));
    }
    Ok(mesh)
}

/// Whether the PLY file at `path` gives its vertices normals (`nx`, `ny`, `nz`), read
/// from its header alone; `false` when it cannot be read.
pub fn ply_has_normals(path: &Path) -> bool {
    let Ok(file) = File::open(path) else { return false };
    let mut reader = ply_rs_bw::parser::Reader::new(BufReader::new(file));
    let Ok(header) = Parser::<DefaultElement>::new().read_header(&mut reader) else { return false };
    header.elements.get("vertex").is_some_and(|v| ["nx", "ny", "nz"].iter().all(|n| v.properties.contains_key(*n)))
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
    let pair = |v: &DefaultElement, names: [&str; 2]| Some((scalar(v.get(names[0]))?, scalar(v.get(names[1]))?));
    let normals: Option<Vec<Vec3>> = vertices
        .iter()
        .map(|v| Some(Vec3::new(scalar(v.get("nx"))?, scalar(v.get("ny"))?, scalar(v.get("nz"))?)))
        .collect();
    let uv_names = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"], ["texture_s", "texture_t"]];
    let uvs: Option<Vec<Vec2>> = vertices
        .iter()
        .map(|v| uv_names.iter().find_map(|names| pair(v, *names)).map(|(u, v)| Vec2::new(u, v)))
        .collect();
    let mut triangles = Vec::new();
    for (i, face) in ply.payload.get("face").map(Vec::as_slice).unwrap_or_default().iter().enumerate() {
        let indices = index_list(face.get("vertex_indices").or_else(|| face.get("vertex_index")))
            .ok_or_else(|| format!("face {i} lacks a non-negative vertex_indices list"))?;
        // Fan polygons into triangles.
        for k in 1..indices.len().saturating_sub(1) {
            triangles.push([indices[0], indices[k], indices[k + 1]]);
        }
    }
    Ok(MeshData {
        normals: normals.filter(|n| !n.is_empty()),
        uvs: uvs.filter(|t| !t.is_empty()),
        positions,
        triangles,
        face_materials: None,
    })
}
