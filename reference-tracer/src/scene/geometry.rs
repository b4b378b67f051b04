//! A scene's shapes as triangles: their positions, normals, texture coordinates and
//! materials, gathered into the arrays the tracer indexes.

use std::path::Path;

use super::{mesh, MeshData, SceneError, ShapeDescription};
use glam::{Mat3, Mat4, Vec2, Vec3};
use guiding_core::Triangle;

/// One shape's triangles before they join the scene.
pub(super) struct ShapeGeometry {
    /// The shape's material, or `None` for per-face MTL materials.
    pub(super) material: Option<String>,
    pub(super) mesh: MeshData,
    /// Each face's front is the side its vertex normals point to.
    pub(super) front_from_normals: bool,
    /// Reverse every face after that.
    pub(super) flip: bool,
}

pub(super) fn shape_geometry(
    shape: &ShapeDescription,
    folder: &Path,
    path: &Path,
    index: usize,
) -> Result<ShapeGeometry, SceneError> {
    let error = |field: &str, message: String| SceneError::new(path, format!("shapes[{index}].{field}"), message);
    match shape {
        ShapeDescription::Mesh { file, material, transform, face_normals, flip, front_from_normals } => {
            let mut mesh = mesh::load_mesh(&folder.join(file), path, &format!("shapes[{index}].file"))?;
            if *face_normals {
                mesh.normals = None;
            }
            if let Some(rows) = transform {
                let matrix = Mat4::from_cols_array_2d(rows).transpose();
                let determinant = matrix.determinant();
                if !matrix.is_finite() || determinant == 0.0 || !determinant.is_finite() {
                    return Err(error("transform", "must be finite and invertible".into()));
                }
                for p in &mut mesh.positions {
                    *p = matrix.transform_point3(*p);
                }
                // Normals transform by the inverse transpose.
                let normal_matrix = Mat3::from_mat4(matrix).inverse().transpose();
                for n in mesh.normals.iter_mut().flatten() {
                    *n = normal_matrix * *n;
                }
            }
            if mesh.positions.iter().any(|p| !p.is_finite()) {
                return Err(error("transform", "moves a vertex to infinity".into()));
            }
            let geometry = ShapeGeometry {
                material: material.clone(),
                mesh,
                front_from_normals: *front_from_normals,
                flip: *flip,
            };
            Ok(geometry)
        }
        ShapeDescription::Quad { corners, material } => {
            let positions: Vec<Vec3> = corners.iter().map(|&c| Vec3::from(c)).collect();
            if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
                return Err(error(&format!("corners[{i}]"), "must be finite".into()));
            }
            let uvs = Some(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]);
            let mesh = MeshData { positions, triangles: vec![[0, 1, 2], [0, 2, 3]], uvs, ..Default::default() };
            Ok(ShapeGeometry { material: Some(material.clone()), mesh, front_from_normals: false, flip: false })
        }
        ShapeDescription::Triangles { positions, indices, normals, uvs, front_from_normals, material } => {
            let positions: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
            if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
                return Err(error(&format!("positions[{i}]"), "must be finite".into()));
            }
            if indices.len() % 3 != 0 {
                return Err(error("indices", format!("{} indices is not a multiple of 3", indices.len())));
            }
            if let Some(i) = indices.iter().position(|&v| v as usize >= positions.len()) {
                let message = format!("index {} out of range ({} positions)", indices[i], positions.len());
                return Err(error(&format!("indices[{i}]"), message));
            }
            let per_vertex = |field: &str, count: usize| {
                if count == positions.len() {
                    Ok(())
                } else {
                    Err(error(field, format!("{count} entries for {} positions", positions.len())))
                }
            };
            let normals = match normals {
                None => None,
                Some(normals) => {
                    per_vertex("normals", normals.len())?;
                    let normals: Vec<Vec3> = normals.iter().map(|&n| Vec3::from(n)).collect();
                    if let Some(i) = normals.iter().position(|n| !n.is_finite()) {
                        return Err(error(&format!("normals[{i}]"), "must be finite".into()));
                    }
                    Some(normals)
                }
            };
            let uvs = match uvs {
                None => None,
                Some(uvs) => {
                    per_vertex("uvs", uvs.len())?;
                    let uvs: Vec<Vec2> = uvs.iter().map(|&t| Vec2::from(t)).collect();
                    if let Some(i) = uvs.iter().position(|t| !t.is_finite()) {
                        return Err(error(&format!("uvs[{i}]"), "must be finite".into()));
                    }
                    Some(uvs)
                }
            };
            let triangles = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            let mesh = MeshData { positions, triangles, normals, uvs, face_materials: None };
            Ok(ShapeGeometry {
                material: Some(material.clone()),
                mesh,
                front_from_normals: *front_from_normals,
                flip: false,
            })
        }
    }
}

/// Gathers the triangles of every shape, with their normals, texture coordinates and
/// materials; drops zero-area triangles.
#[derive(Default)]
pub(super) struct GeometryBuilder {
    pub(super) triangles: Vec<Triangle>,
    pub(super) normals: Vec<Vec3>,
    pub(super) triangle_materials: Vec<u32>,
    pub(super) vertex_normals: Vec<[Vec3; 3]>,
    pub(super) vertex_uvs: Vec<[Vec2; 3]>,
    /// Whether some shape had vertex normals / texture coordinates.
    pub(super) any_normals: bool,
    pub(super) degenerate: usize,
}

impl GeometryBuilder {
    pub(super) fn add(&mut self, shape: ShapeGeometry, face_materials: &[u32]) {
        let mesh = &shape.mesh;
        self.any_normals |= mesh.normals.is_some();
        for (face, &material) in mesh.triangles.iter().zip(face_materials) {
            let mut face = *face;
            let vertex_normals = mesh.normals.as_ref().map(|n| face.map(|i| n[i as usize]));
            let winding = Triangle::new(
                mesh.positions[face[0] as usize],
                mesh.positions[face[1] as usize],
                mesh.positions[face[2] as usize],
            )
            .normal();
            let mut reverse = shape.flip;
            if let (true, Some(n), Some(winding)) = (shape.front_from_normals, vertex_normals, winding) {
                reverse ^= (n[0] + n[1] + n[2]).dot(winding) < 0.0;
            }
            if reverse {
                face.swap(1, 2);
            }
            let triangle = Triangle::new(
                mesh.positions[face[0] as usize],
                mesh.positions[face[1] as usize],
                mesh.positions[face[2] as usize],
            );
            let Some(normal) = triangle.normal() else {
                self.degenerate += 1;
                continue;
            };
            self.triangles.push(triangle);
            self.normals.push(normal);
            self.triangle_materials.push(material);
            let unit = |n: Vec3| n.try_normalize().unwrap_or(normal);
            self.vertex_normals.push(mesh.normals.as_ref().map_or([normal; 3], |n| face.map(|i| unit(n[i as usize]))));
            // pbrt's default parameterisation where a mesh has none.
            let default_uvs = [Vec2::ZERO, Vec2::X, Vec2::ONE];
            self.vertex_uvs.push(mesh.uvs.as_ref().map_or(default_uvs, |t| face.map(|i| t[i as usize])));
        }
    }

    /// Drops the per-vertex tables nothing needs.
    pub(super) fn finish(mut self, textured: bool) -> Self {
        if !self.any_normals {
            self.vertex_normals = Vec::new();
        }
        if !textured {
            self.vertex_uvs = Vec::new();
        }
        self
    }
}
