//! Scenes: read a scene file (SCENE_FORMAT.md), check every value, and build the
//! geometry, materials, lights and environment the tracer renders.

mod description;
mod error;
mod mesh;

use std::path::{Path, PathBuf};

use std::collections::HashMap;

use glam::{Mat3, Mat4, Vec2, Vec3};
use guiding_core::environment::SunDisk;
use guiding_core::Triangle;

use crate::camera::{Camera, FovAxis};
use crate::color::{is_valid_radiance, luminance};
use crate::environment::{Environment, LatLongMap, Sky, Sun};
use crate::lights::AreaLights;
use crate::material::{ComplexIor, Material, Plastic, Surface};
use crate::texture::Texture;
pub use description::{
    CameraDescription, EnvironmentDescription, MaterialDescription, SceneDescription, ShapeDescription, SunDescription,
    TextureDescription, TextureEncoding,
};
pub use error::SceneError;
pub use mesh::{parse_mesh, ply_has_normals, MeshData, MeshFormat, MtlMaterial};

/// The largest image side accepted, pixels.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// A scene ready to render.
pub struct Scene {
    /// The file it was read from.
    pub path: PathBuf,
    /// The camera.
    pub camera: Camera,
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
    /// Reads and checks a scene file: the project's JSON, or by its extension a pbrt-v3
    /// (`.pbrt`) or Mitsuba (`.xml`) scene. Every error names the file and where in it.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        match crate::import::SceneFormat::of(path)? {
            crate::import::SceneFormat::Json => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| SceneError::new(path, "", format!("cannot read: {e}")))?;
                Self::from_json(path, &text)
            }
            _ => {
                let imported = crate::import::import(path)?;
                let mut scene = Self::from_description(path, imported.description)?;
                scene.warnings.splice(0..0, imported.warnings);
                Ok(scene)
            }
        }
    }

    /// Builds a scene from the JSON `text` of the file `path` (named in errors; relative
    /// file names resolve against its folder).
    pub fn from_json(path: &Path, text: &str) -> Result<Scene, SceneError> {
        let deserializer = &mut serde_json::Deserializer::from_str(text);
        let description: SceneDescription = serde_path_to_error::deserialize(deserializer).map_err(|e| {
            let location = match e.path().to_string().as_str() {
                "." => String::new(),
                p => p.to_string(),
            };
            let inner = e.inner();
            SceneError::new(path, location, format!("{inner} (line {}, column {})", inner.line(), inner.column()))
        })?;
        Self::from_description(path, description)
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

fn reflectance(values: [f32; 3], field: &'static str) -> Result<Vec3, (&'static str, String)> {
    let v = Vec3::from(values);
    if v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0 {
        Ok(v)
    } else {
        Err((field, format!("{values:?} must lie in [0, 1]")))
    }
}

fn build_texture(texture: &TextureDescription, folder: &Path) -> Result<Texture, (&'static str, String)> {
    let uv_transform = |scale: Option<[f32; 2]>, offset: Option<[f32; 2]>| {
        let (scale, offset) = (Vec2::from(scale.unwrap_or([1.0; 2])), Vec2::from(offset.unwrap_or([0.0; 2])));
        if !scale.is_finite() {
            return Err(("uv_scale", format!("{scale:?} must be finite")));
        }
        if !offset.is_finite() {
            return Err(("uv_offset", format!("{offset:?} must be finite")));
        }
        Ok((scale, offset))
    };
    match texture {
        TextureDescription::Image { file, encoding, uv_scale, uv_offset } => {
            let (scale, offset) = uv_transform(*uv_scale, *uv_offset)?;
            let image_path = folder.join(file);
            let srgb = *encoding != Some(TextureEncoding::Linear);
            let texture =
                Texture::load(&image_path, srgb).map_err(|e| ("file", format!("{}: {e}", image_path.display())))?;
            Ok(texture.with_uv_transform(scale, offset))
        }
        TextureDescription::Checkerboard { even, odd, uv_scale, uv_offset } => {
            let (scale, offset) = uv_transform(*uv_scale, *uv_offset)?;
            let checks = Texture::checkerboard(reflectance(*even, "even")?, reflectance(*odd, "odd")?);
            Ok(checks.with_uv_transform(scale, offset))
        }
    }
}

fn positive_finite(value: f32, field: &'static str) -> Result<f32, (&'static str, String)> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err((field, format!("{value} must be finite and positive")))
    }
}

fn build_material(
    material: &MaterialDescription,
    textures: &HashMap<&str, u32>,
) -> Result<Material, (&'static str, String)> {
    let texture = |name: &Option<String>, field: &'static str| match name {
        None => Ok(None),
        Some(name) => {
            textures.get(name.as_str()).copied().map(Some).ok_or((field, format!("unknown texture \"{name}\"")))
        }
    };
    // A colour that a texture may multiply: required unless the texture is given.
    let scaled = |value: Option<[f32; 3]>, field: &'static str, textured: bool| match value {
        Some(v) => reflectance(v, field),
        None if textured => Ok(Vec3::ONE),
        None => Err((field, "missing (give a colour or a texture)".to_string())),
    };
    let no_texture = None;
    let (surface, emission, albedo_texture, opacity_texture) = match material {
        MaterialDescription::Diffuse { albedo, albedo_texture, opacity_texture, emission } => {
            let albedo_texture = texture(albedo_texture, "albedo_texture")?;
            let albedo = scaled(*albedo, "albedo", albedo_texture.is_some())?;
            (Surface::Diffuse { albedo }, emission, albedo_texture, opacity_texture)
        }
        MaterialDescription::Conductor { specular, specular_texture, alpha, eta, k, opacity_texture, emission } => {
            if !(alpha.is_finite() && *alpha >= 0.0) {
                return Err(("alpha", format!("{alpha} must be finite and non-negative")));
            }
            let specular_texture = texture(specular_texture, "specular_texture")?;
            let specular = scaled(Some(specular.unwrap_or([1.0; 3])), "specular", true)?;
            let ior = match (eta, k) {
                (None, None) => None,
                (Some(eta), Some(k)) => {
                    let (eta, k) = (Vec3::from(*eta), Vec3::from(*k));
                    if !(eta.is_finite() && eta.min_element() > 0.0) {
                        return Err(("eta", format!("{eta:?} must be finite and positive")));
                    }
                    if !(k.is_finite() && k.min_element() >= 0.0) {
                        return Err(("k", format!("{k:?} must be finite and non-negative")));
                    }
                    Some(ComplexIor { eta, k })
                }
                (Some(_), None) => return Err(("k", "missing: `eta` needs `k`".to_string())),
                (None, Some(_)) => return Err(("eta", "missing: `k` needs `eta`".to_string())),
            };
            (Surface::Conductor { specular, alpha: *alpha, ior }, emission, specular_texture, opacity_texture)
        }
        MaterialDescription::Dielectric { ior, emission } => {
            (Surface::Dielectric { ior: positive_finite(*ior, "ior")? }, emission, None, &no_texture)
        }
        MaterialDescription::ThinDielectric { ior, emission } => {
            (Surface::ThinDielectric { ior: positive_finite(*ior, "ior")? }, emission, None, &no_texture)
        }
        MaterialDescription::Plastic { albedo, albedo_texture, specular, ior, alpha, opacity_texture, emission } => {
            let albedo_texture = texture(albedo_texture, "albedo_texture")?;
            let albedo = scaled(*albedo, "albedo", albedo_texture.is_some())?;
            let specular = specular.unwrap_or(1.0);
            if !(0.0..=1.0).contains(&specular) {
                return Err(("specular", format!("{specular} must lie in [0, 1]")));
            }
            let ior = ior.unwrap_or(1.5);
            if !(ior.is_finite() && ior > 1.0) {
                return Err(("ior", format!("{ior} must be finite and above 1")));
            }
            if !(alpha.is_finite() && *alpha >= 0.0) {
                return Err(("alpha", format!("{alpha} must be finite and non-negative")));
            }
            (Surface::Plastic(Plastic::new(albedo, specular, ior, *alpha)), emission, albedo_texture, opacity_texture)
        }
    };
    let opacity_texture = texture(opacity_texture, "opacity_texture")?;
    let emission = Vec3::from(emission.unwrap_or([0.0; 3]));
    if !is_valid_radiance(emission) {
        return Err(("emission", format!("{emission:?} must be finite and non-negative radiance")));
    }
    Ok(Material { surface, emission, albedo_texture, opacity_texture })
}

/// A scene material for an MTL material: diffuse `Kd` (clamped to [0, 1]), emitting `Ke`.
fn mtl_material(mtl: &MtlMaterial) -> Material {
    let finite = |v: [f32; 3]| {
        let v = Vec3::from(v);
        if v.is_finite() {
            v.max(Vec3::ZERO)
        } else {
            Vec3::ZERO
        }
    };
    Material::new(Surface::Diffuse { albedo: finite(mtl.diffuse).min(Vec3::ONE) }, finite(mtl.emission))
}

/// One shape's triangles before they join the scene.
struct ShapeGeometry {
    /// The shape's material, or `None` for per-face MTL materials.
    material: Option<String>,
    mesh: MeshData,
    /// Each face's front is the side its vertex normals point to.
    front_from_normals: bool,
    /// Reverse every face after that.
    flip: bool,
}

fn shape_geometry(
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
struct GeometryBuilder {
    triangles: Vec<Triangle>,
    normals: Vec<Vec3>,
    triangle_materials: Vec<u32>,
    vertex_normals: Vec<[Vec3; 3]>,
    vertex_uvs: Vec<[Vec2; 3]>,
    /// Whether some shape had vertex normals / texture coordinates.
    any_normals: bool,
    degenerate: usize,
}

impl GeometryBuilder {
    fn add(&mut self, shape: ShapeGeometry, face_materials: &[u32]) {
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
    fn finish(mut self, textured: bool) -> Self {
        if !self.any_normals {
            self.vertex_normals = Vec::new();
        }
        if !textured {
            self.vertex_uvs = Vec::new();
        }
        self
    }
}

fn build_environment(env: &EnvironmentDescription, folder: &Path, path: &Path) -> Result<Environment, SceneError> {
    let (sky, sun) = match env {
        EnvironmentDescription::Constant { radiance, sun } => {
            let radiance = Vec3::from(*radiance);
            if !is_valid_radiance(radiance) {
                let message = format!("{radiance:?} must be finite and non-negative radiance");
                return Err(SceneError::new(path, "environment.radiance", message));
            }
            (Sky::Constant(radiance), sun)
        }
        EnvironmentDescription::Image { file, scale, rotation, sun } => {
            let scale = scale.unwrap_or(1.0);
            if !(scale.is_finite() && scale >= 0.0) {
                return Err(SceneError::new(
                    path,
                    "environment.scale",
                    format!("{scale} must be finite and non-negative"),
                ));
            }
            let image_path = folder.join(file);
            let fail = |message: String| {
                SceneError::new(path, "environment.file", format!("{}: {message}", image_path.display()))
            };
            let image = crate::output::read_image(&image_path).map_err(fail)?;
            if image.width == 0 || image.height == 0 {
                return Err(fail("image has zero size".into()));
            }
            if let Some(i) = image.pixels.iter().position(|&p| !is_valid_radiance(p)) {
                return Err(fail(format!(
                    "texel ({}, {}) is {:?}: radiance must be finite and non-negative",
                    i % image.width,
                    i / image.width,
                    image.pixels[i]
                )));
            }
            let mut texels: Vec<Vec3> = image.pixels.iter().map(|&p| p * scale).collect();
            if let Some(rows) = rotation {
                let to_world = Mat3::from_cols_array_2d(rows).transpose();
                let orthonormal = (to_world * to_world.transpose()).abs_diff_eq(Mat3::IDENTITY, 1e-3)
                    && (to_world.determinant() - 1.0).abs() < 1e-3;
                if !orthonormal {
                    let message = "must be a rotation (orthonormal, determinant 1)".to_string();
                    return Err(SceneError::new(path, "environment.rotation", message));
                }
                texels = rotate_lat_long(image.width, image.height, &texels, to_world);
            }
            (Sky::Image(LatLongMap::new(image.width, image.height, texels)), sun)
        }
    };
    let sun = match sun {
        Some(sun) => Some(build_sun(sun, path)?),
        None => None,
    };
    Ok(Environment::new(sky, sun))
}

/// The lat-long map that shows in direction d what `texels` show in direction
/// `to_world⁻¹ · d`: rotated about +y by whole texels, an exact shift of the columns;
/// otherwise resampled bilinearly (a slight blur).
fn rotate_lat_long(width: usize, height: usize, texels: &[Vec3], to_world: Mat3) -> Vec<Vec3> {
    use guiding_core::environment::lat_long::{direction_of_uv, uv_of_direction};
    let about_y = (to_world * Vec3::Y).abs_diff_eq(Vec3::Y, 1e-6);
    if about_y {
        // The map's −z (u = 0.5) goes to the world's to_world·(−z): a shift in u.
        let u_shift = uv_of_direction(to_world * Vec3::NEG_Z).x - 0.5;
        let columns = u_shift * width as f32;
        if (columns - columns.round()).abs() < 1e-3 {
            let shift = (columns.round() as i64).rem_euclid(width as i64) as usize;
            let mut rotated = vec![Vec3::ZERO; texels.len()];
            for row in 0..height {
                for column in 0..width {
                    rotated[row * width + (column + shift) % width] = texels[row * width + column];
                }
            }
            return rotated;
        }
    }
    let to_local = to_world.transpose();
    let at = |x: i64, y: i64| {
        let y = y.clamp(0, height as i64 - 1) as usize;
        texels[y * width + x.rem_euclid(width as i64) as usize]
    };
    let mut rotated = Vec::with_capacity(texels.len());
    for row in 0..height {
        for column in 0..width {
            let uv = Vec2::new((column as f32 + 0.5) / width as f32, (row as f32 + 0.5) / height as f32);
            let source = uv_of_direction(to_local * direction_of_uv(uv));
            let (x, y) = (source.x * width as f32 - 0.5, source.y * height as f32 - 0.5);
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
            let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
            rotated.push(top * (1.0 - fy) + bottom * fy);
        }
    }
    rotated
}

fn build_sun(sun: &SunDescription, path: &Path) -> Result<Sun, SceneError> {
    let radiance = Vec3::from(sun.radiance);
    if !is_valid_radiance(radiance) {
        let message = format!("{radiance:?} must be finite and non-negative radiance");
        return Err(SceneError::new(path, "environment.sun.radiance", message));
    }
    let disk = SunDisk::new(Vec3::from(sun.direction), sun.angular_radius_deg.to_radians(), luminance(radiance))
        .map_err(|e| {
            let field = match &e {
                guiding_core::Error::InvalidSetting { name: "sun.direction", .. } => "environment.sun.direction",
                _ => "environment.sun.angular_radius_deg",
            };
            SceneError::new(path, field, e.to_string())
        })?;
    Ok(Sun { disk, radiance })
}
