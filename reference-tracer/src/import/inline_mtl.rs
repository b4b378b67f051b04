//! A scene's OBJ meshes whose faces take their MTL file's materials, written out as one
//! inline `triangles` shape per material, each material defined in the scene: the same
//! scene for a renderer that reads the project's JSON but not MTL files (the Mitsuba
//! peer, whose OBJ loader knows no per-face materials).

use std::collections::HashMap;
use std::path::Path;

use crate::scene::{load_mesh, MaterialDescription, MtlMaterial, SceneDescription, SceneError, ShapeDescription};

/// Replaces every mesh of `description` (read from `scene_file`) that has no `material`
/// of its own by one `triangles` shape per MTL material its faces use, with the vertices
/// those faces use (and their normals, unless the mesh shades by face normals). A
/// material the scene does not define by that name is added as the loader builds it:
/// diffuse `Kd` clamped to [0, 1], emitting `Ke`. Errors name the shape: its file, or a
/// transform or flip (which `triangles` shapes lack). Build the scene first: a face
/// without a material is the loader's error, and is left out here.
pub fn inline_mtl_meshes(description: &mut SceneDescription, scene_file: &Path) -> Result<(), SceneError> {
    let folder = scene_file.parent().unwrap_or(Path::new("."));
    let mut shapes = Vec::with_capacity(description.shapes.len());
    for (index, shape) in std::mem::take(&mut description.shapes).into_iter().enumerate() {
        let ShapeDescription::Mesh { file, material: None, transform, face_normals, flip, front_from_normals } = &shape
        else {
            shapes.push(shape);
            continue;
        };
        let location = format!("shapes[{index}]");
        if transform.is_some() || *flip {
            let message = "a mesh that takes its MTL materials cannot be written inline with a transform or flip";
            return Err(SceneError::new(scene_file, location, message));
        }
        let mesh = load_mesh(&folder.join(file), scene_file, &location)?;
        // A mesh without MTL materials, or with a face lacking one, is the loader's error
        // (the caller builds the scene first): such faces are never written.
        let Some((mtl, faces)) = &mesh.face_materials else {
            shapes.push(shape);
            continue;
        };
        let normals = mesh.normals.as_ref().filter(|_| !face_normals);
        for (id, material) in mtl.iter().enumerate() {
            // This material's faces, their vertices renumbered in order of first use.
            let mut renumbered = HashMap::new();
            let (mut positions, mut vertex_normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
            for (triangle, _) in mesh.triangles.iter().zip(faces).filter(|(_, f)| **f == Some(id as u32)) {
                for &vertex in triangle {
                    let next = positions.len() as u32;
                    let new = *renumbered.entry(vertex).or_insert_with(|| {
                        positions.push(mesh.positions[vertex as usize].to_array());
                        if let Some(normals) = normals {
                            vertex_normals.push(normals[vertex as usize].to_array());
                        }
                        next
                    });
                    indices.push(new);
                }
            }
            if indices.is_empty() {
                continue;
            }
            description.materials.entry(material.name.clone()).or_insert_with(|| diffuse(material));
            shapes.push(ShapeDescription::Triangles {
                positions,
                indices,
                normals: normals.map(|_| vertex_normals),
                uvs: None,
                front_from_normals: *front_from_normals,
                material: material.name.clone(),
            });
        }
    }
    description.shapes = shapes;
    Ok(())
}

/// The scene material the loader builds for an MTL material.
fn diffuse(mtl: &MtlMaterial) -> MaterialDescription {
    let (albedo, emission) = mtl.albedo_and_emission();
    MaterialDescription::Diffuse {
        albedo: Some(albedo.to_array()),
        albedo_texture: None,
        opacity_texture: None,
        emission: (emission.max_element() > 0.0).then_some(emission.to_array()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    fn original_cornell_box() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box-original/scene.json")
    }

    /// McGuire's original Cornell box (one OBJ, eight MTL materials) written inline is
    /// the same scene: the same triangles, each with the same material.
    #[test]
    fn an_obj_with_mtl_materials_inline_is_the_same_scene() {
        let path = original_cornell_box();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut description = SceneDescription::from_json(&path, &text).unwrap();
        inline_mtl_meshes(&mut description, &path).unwrap();
        assert!(description.shapes.iter().all(|s| matches!(s, ShapeDescription::Triangles { .. })));
        assert_eq!(description.materials.len(), 8, "{:?}", description.materials.keys());
        let inline = Scene::from_description(&path, description).unwrap();
        let original = Scene::load(&path).unwrap();
        assert_eq!(inline.triangles.len(), original.triangles.len());
        // Shapes come per material: match triangles by their vertices.
        let key = |s: &Scene, t: usize| {
            let material = &s.materials[s.triangle_materials[t] as usize];
            let vertices = s.triangles[t].vertices.map(|v| v.to_array().map(f32::to_bits));
            (vertices, material.emission.to_array().map(f32::to_bits), format!("{:?}", material.surface))
        };
        let mut a: Vec<_> = (0..inline.triangles.len()).map(|t| key(&inline, t)).collect();
        let mut b: Vec<_> = (0..original.triangles.len()).map(|t| key(&original, t)).collect();
        a.sort();
        b.sort();
        assert_eq!(a, b);
        assert!(inline.lights.len() == original.lights.len() && !inline.lights.is_empty());
    }

    #[test]
    fn a_transformed_mtl_mesh_is_refused_by_name() {
        let path = original_cornell_box();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut description = SceneDescription::from_json(&path, &text).unwrap();
        if let ShapeDescription::Mesh { flip, .. } = &mut description.shapes[0] {
            *flip = true;
        }
        let error = inline_mtl_meshes(&mut description, &path).unwrap_err().to_string();
        assert!(error.contains("shapes[0]") && error.contains("flip"), "{error}");
    }
}
