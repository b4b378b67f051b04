//! Scenes: read a scene file (SCENE_FORMAT.md), check every value, and build the
//! geometry, materials, lights and environment the tracer renders.

mod description;
mod environment;
mod error;
mod geometry;
mod materials;
mod mesh;

use environment::build_environment;
use geometry::{shape_geometry, GeometryBuilder};
use materials::{build_material, build_texture, mtl_material};

use std::path::{Path, PathBuf};

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use guiding_core::Triangle;

use crate::camera::{Camera, FovAxis};
use crate::environment::Environment;
use crate::lights::AreaLights;
use crate::material::Material;
use crate::texture::Texture;
pub use description::{
    CameraDescription, EnvironmentDescription, MaterialDescription, SceneDescription, ShapeDescription, SunDescription,
    TextureDescription, TextureEncoding,
};
pub use error::SceneError;
pub use mesh::{load_mesh, parse_mesh, ply_has_normals, MeshData, MeshFormat, MtlMaterial};

/// The largest image side accepted, pixels.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// A scene ready to render.
pub struct Scene {
    /// The file it was read from.
    pub path: PathBuf,
    /// The camera.
    pub camera: Camera,
    /// An animation's camera views (eye, target), or none ([`frame_camera`](Self::frame_camera)).
    pub camera_keyframes: Vec<(Vec3, Vec3)>,
    /// Every triangle, in shape order.
    pub triangles: Vec<Triangle>,
    /// Unit geometric normal of each triangle (from its winding).
    pub normals: Vec<Vec3>,
    /// Material index of each triangle.
    pub triangle_materials: Vec<u32>,
    /// Per-triangle vertex shading normals (unit), or empty when no shape has any (the
    /// geometric normal shades everywhere); triangles of shapes without them repeat
    /// their geometric normal.
    pub vertex_normals: Vec<[Vec3; 3]>,
    /// Per-triangle vertex texture coordinates, or empty when no material is textured.
    pub vertex_uvs: Vec<[Vec2; 3]>,
    /// Materials: the scene file's in name order, then those of OBJ MTL files.
    pub materials: Vec<Material>,
    /// Material names, parallel to `materials`.
    pub material_names: Vec<String>,
    /// Textures materials refer to by index.
    pub textures: Vec<Texture>,
    /// Emissive triangles.
    pub lights: AreaLights,
    /// Light from infinitely far away, if any.
    pub environment: Option<Environment>,
    /// Things skipped while loading (degenerate triangles), for the user to see.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Builds a scene from the JSON `text` of the file `path` (named in errors; relative
    /// file names resolve against its folder).
    pub fn from_json(path: &Path, text: &str) -> Result<Scene, SceneError> {
        Self::from_description(path, SceneDescription::from_json(path, text)?)
    }

    /// Builds a scene from a parsed description; relative file names resolve against the
    /// folder of `path`.
    pub fn from_description(path: &Path, description: SceneDescription) -> Result<Scene, SceneError> {
        let folder = path.parent().unwrap_or(Path::new("."));
        let error = |location: String, message: String| SceneError::new(path, location, message);
        if description.format != 1 {
            return Err(error("format".into(), format!("format {} is not supported (expected 1)", description.format)));
        }
        let camera =
            build_camera(&description.camera).map_err(|(field, message)| error(format!("camera.{field}"), message))?;
        let camera_keyframes = build_keyframes(&camera, &description.camera)
            .map_err(|(index, field, message)| error(format!("camera.keyframes[{index}].{field}"), message))?;

        let mut textures = Vec::new();
        let mut texture_index = HashMap::new();
        for (name, texture) in &description.textures {
            let built = build_texture(texture, folder)
                .map_err(|(field, message)| error(format!("textures.{name}.{field}"), message))?;
            texture_index.insert(name.as_str(), textures.len() as u32);
            textures.push(built);
        }
        let mut materials = Vec::new();
        let mut material_names = Vec::new();
        for (name, material) in &description.materials {
            let built = build_material(material, &texture_index)
                .map_err(|(field, message)| error(format!("materials.{name}.{field}"), message))?;
            materials.push(built);
            material_names.push(name.clone());
        }
        let mut material_index: HashMap<String, u32> =
            material_names.iter().enumerate().map(|(i, name)| (name.clone(), i as u32)).collect();

        let mut geometry = GeometryBuilder::default();
        for (index, shape) in description.shapes.iter().enumerate() {
            let shape_geometry = shape_geometry(shape, folder, path, index)?;
            let face_materials: Vec<u32> = match (&shape_geometry.material, &shape_geometry.mesh.face_materials) {
                (Some(name), _) => {
                    let material = *material_index.get(name.as_str()).ok_or_else(|| {
                        error(format!("shapes[{index}].material"), format!("unknown material \"{name}\""))
                    })?;
                    vec![material; shape_geometry.mesh.triangles.len()]
                }
                (None, Some((mtl, faces))) => {
                    // The OBJ's own materials, unless the scene file defines one by the same name.
                    let ids: Vec<u32> = mtl
                        .iter()
                        .map(|m| {
                            *material_index.entry(m.name.clone()).or_insert_with(|| {
                                materials.push(mtl_material(m));
                                material_names.push(m.name.clone());
                                (materials.len() - 1) as u32
                            })
                        })
                        .collect();
                    let missing = faces.iter().position(Option::is_none);
                    if let Some(face) = missing {
                        let message =
                            format!("face {face} of the OBJ has no MTL material; give the shape a `material`");
                        return Err(error(format!("shapes[{index}].material"), message));
                    }
                    faces.iter().map(|f| ids[f.unwrap_or(0) as usize]).collect()
                }
                (None, None) => {
                    let message = "missing: the mesh has no MTL materials to take instead".to_string();
                    return Err(error(format!("shapes[{index}].material"), message));
                }
            };
            geometry.add(shape_geometry, &face_materials);
        }
        let GeometryBuilder { triangles, normals, triangle_materials, vertex_normals, vertex_uvs, degenerate, .. } =
            geometry.finish(materials.iter().any(|m| m.albedo_texture.is_some() || m.opacity_texture.is_some()));
        let mut warnings = Vec::new();
        if degenerate > 0 {
            warnings.push(format!("{degenerate} degenerate (zero-area) triangles dropped"));
        }
        if triangles.is_empty() {
            return Err(error("shapes".into(), "the scene has no triangle with positive area".into()));
        }
        let environment = match &description.environment {
            None => None,
            Some(env) => Some(build_environment(env, folder, path)?),
        };
        let lights = AreaLights::new(&triangles, |i| materials[triangle_materials[i] as usize].emission);
        if lights.is_empty() && environment.is_none() {
            warnings.push("nothing emits light: the image will be black".into());
        }
        Ok(Scene {
            path: path.to_path_buf(),
            camera,
            camera_keyframes,
            triangles,
            normals,
            triangle_materials,
            vertex_normals,
            vertex_uvs,
            materials,
            material_names,
            textures,
            lights,
            environment,
            warnings,
        })
    }

    /// Cuts every emissive triangle into `split`² sub-triangles, each a light of its own
    /// (see [`AreaLights::split`]); 1 makes every light a whole triangle again.
    pub fn split_lights(&mut self, split: u32) {
        let (materials, triangle_materials) = (&self.materials, &self.triangle_materials);
        self.lights = AreaLights::split(&self.triangles, |i| materials[triangle_materials[i] as usize].emission, split);
    }

    /// The material of triangle `triangle` (untextured).
    pub fn material(&self, triangle: u32) -> &Material {
        &self.materials[self.triangle_materials[triangle as usize] as usize]
    }

    /// The unit shading normal of `triangle` at `barycentrics` (of vertices 1 and 2):
    /// its vertex normals interpolated, or its geometric normal.
    pub fn shading_normal(&self, triangle: u32, barycentrics: Vec2) -> Vec3 {
        let Some(n) = self.vertex_normals.get(triangle as usize) else { return self.normals[triangle as usize] };
        let (b1, b2) = (barycentrics.x, barycentrics.y);
        (n[0] * (1.0 - b1 - b2) + n[1] * b1 + n[2] * b2).try_normalize().unwrap_or(self.normals[triangle as usize])
    }

    /// Texture coordinates of `triangle` at `barycentrics`.
    pub fn uv(&self, triangle: u32, barycentrics: Vec2) -> Vec2 {
        let Some(t) = self.vertex_uvs.get(triangle as usize) else { return barycentrics };
        let (b1, b2) = (barycentrics.x, barycentrics.y);
        t[0] * (1.0 - b1 - b2) + t[1] * b1 + t[2] * b2
    }

    /// The material of `triangle` at `barycentrics`, textures applied, and its opacity.
    pub fn material_at(&self, triangle: u32, barycentrics: Vec2) -> (Material, f32) {
        let material = self.material(triangle);
        if material.albedo_texture.is_none() && material.opacity_texture.is_none() {
            return (*material, 1.0);
        }
        let uv = self.uv(triangle, barycentrics);
        (material.at(&self.textures, uv), material.opacity(&self.textures, uv))
    }

    /// Whether any material has an opacity texture (shadow rays then see through it).
    pub fn has_masks(&self) -> bool {
        self.materials.iter().any(|m| m.opacity_texture.is_some())
    }

    /// The camera of frame `frame` of `frames` (0-based): the keyframes' view there, with
    /// the current camera's size and field of view; the current camera itself when the
    /// scene has no animation.
    pub fn frame_camera(&self, frame: u32, frames: u32) -> Camera {
        crate::animation::keyframe_view(&self.camera_keyframes, frame, frames)
            .and_then(|(eye, target)| self.camera.looking(eye, target))
            .unwrap_or(self.camera)
    }

    /// The bounding box of every triangle, (low, high); inverted (∞, −∞) for no triangles.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.triangles
            .iter()
            .flat_map(|t| t.vertices)
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), v| (low.min(v), high.max(v)))
    }
}

fn finite3(values: [f32; 3]) -> Option<Vec3> {
    let v = Vec3::from(values);
    v.is_finite().then_some(v)
}

/// What is wrong with a keyframe: its index, the field, the message.
type KeyframeError = (usize, &'static str, String);

/// The keyframes as points, each checked to make a camera; errors name the keyframe.
fn build_keyframes(camera: &Camera, description: &CameraDescription) -> Result<Vec<(Vec3, Vec3)>, KeyframeError> {
    let keyframes = &description.keyframes;
    if keyframes.len() == 1 {
        return Err((0, "eye", "an animation needs at least two keyframes (or none)".to_string()));
    }
    keyframes
        .iter()
        .enumerate()
        .map(|(index, keyframe)| {
            let eye = finite3(keyframe.eye).ok_or((index, "eye", "must be finite".to_string()))?;
            let target = finite3(keyframe.target).ok_or((index, "target", "must be finite".to_string()))?;
            camera.looking(eye, target).ok_or((
                index,
                "target",
                "the view direction is zero or parallel to `up`".to_string(),
            ))?;
            Ok((eye, target))
        })
        .collect()
}

fn build_camera(camera: &CameraDescription) -> Result<Camera, (&'static str, String)> {
    let eye = finite3(camera.eye).ok_or(("eye", "must be finite".to_string()))?;
    let target = finite3(camera.target).ok_or(("target", "must be finite".to_string()))?;
    let up = finite3(camera.up).ok_or(("up", "must be finite".to_string()))?;
    let fov = match (camera.fov_y_deg, camera.fov_x_deg) {
        (Some(y), None) => (y, FovAxis::Vertical, "fov_y_deg"),
        (None, Some(x)) => (x, FovAxis::Horizontal, "fov_x_deg"),
        (None, None) => return Err(("fov_y_deg", "missing (give fov_y_deg or fov_x_deg)".to_string())),
        (Some(_), Some(_)) => return Err(("fov_x_deg", "give fov_y_deg or fov_x_deg, not both".to_string())),
    };
    if !(fov.0 > 0.0 && fov.0 < 180.0) {
        return Err((fov.2, format!("{} must be in (0, 180)", fov.0)));
    }
    for (field, side) in [("width", camera.width), ("height", camera.height)] {
        if side == 0 || side > MAX_IMAGE_SIDE {
            return Err((field, format!("{side} must be in 1..={MAX_IMAGE_SIDE}")));
        }
    }
    Camera::oriented(eye, target, up, (fov.0, fov.1), camera.width, camera.height, camera.mirrored)
        .ok_or(("target", "the view direction is zero or parallel to `up`".to_string()))
}
