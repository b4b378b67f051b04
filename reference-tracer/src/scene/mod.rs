//! Scenes: read a scene file (SCENE_FORMAT.md), check every value, and build the
//! geometry, materials, lights and environment the tracer renders.

mod description;
mod error;
mod mesh;

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};
use guiding_core::environment::SunDisk;
use guiding_core::Triangle;

use crate::camera::Camera;
use crate::color::{is_valid_radiance, luminance};
use crate::environment::{Environment, LatLongMap, Sky, Sun};
use crate::lights::AreaLights;
use crate::material::{Material, Surface};
pub use description::{
    CameraDescription, EnvironmentDescription, MaterialDescription, SceneDescription, ShapeDescription, SunDescription,
};
pub use error::SceneError;
pub use mesh::{parse_mesh, MeshData, MeshFormat};

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
    /// Materials, in name order.
    pub materials: Vec<Material>,
    /// Material names, parallel to `materials`.
    pub material_names: Vec<String>,
    /// Emissive triangles.
    pub lights: AreaLights,
    /// Light from infinitely far away, if any.
    pub environment: Option<Environment>,
    /// Things skipped while loading (degenerate triangles), for the user to see.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Reads and checks a scene file. Every error names the file and where in it.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::new(path, "", format!("cannot read: {e}")))?;
        Self::from_json(path, &text)
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

        let mut materials = Vec::new();
        let mut material_names = Vec::new();
        for (name, material) in &description.materials {
            let built = build_material(material)
                .map_err(|(field, message)| error(format!("materials.{name}.{field}"), message))?;
            materials.push(built);
            material_names.push(name.clone());
        }

        let mut triangles = Vec::new();
        let mut normals = Vec::new();
        let mut triangle_materials = Vec::new();
        let mut degenerate = 0usize;
        for (index, shape) in description.shapes.iter().enumerate() {
            let (material_name, positions, faces) = shape_geometry(shape, folder, path, index)?;
            let material = material_names.binary_search_by(|name| name.as_str().cmp(material_name)).map_err(|_| {
                error(format!("shapes[{index}].material"), format!("unknown material \"{material_name}\""))
            })? as u32;
            for face in faces {
                let triangle = Triangle::new(
                    positions[face[0] as usize],
                    positions[face[1] as usize],
                    positions[face[2] as usize],
                );
                let Some(normal) = triangle.normal() else {
                    degenerate += 1;
                    continue;
                };
                triangles.push(triangle);
                normals.push(normal);
                triangle_materials.push(material);
            }
        }
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
            materials,
            material_names,
            lights,
            environment,
            warnings,
        })
    }

    /// The material of triangle `triangle`.
    pub fn material(&self, triangle: u32) -> &Material {
        &self.materials[self.triangle_materials[triangle as usize] as usize]
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
    if !(camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0) {
        return Err(("fov_y_deg", format!("{} must be in (0, 180)", camera.fov_y_deg)));
    }
    for (field, side) in [("width", camera.width), ("height", camera.height)] {
        if side == 0 || side > MAX_IMAGE_SIDE {
            return Err((field, format!("{side} must be in 1..={MAX_IMAGE_SIDE}")));
        }
    }
    Camera::look_at(eye, target, up, camera.fov_y_deg, camera.width, camera.height)
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

fn build_material(material: &MaterialDescription) -> Result<Material, (&'static str, String)> {
    let (surface, emission) = match *material {
        MaterialDescription::Diffuse { albedo, emission } => {
            (Surface::Diffuse { albedo: reflectance(albedo, "albedo")? }, emission)
        }
        MaterialDescription::Conductor { specular, alpha, emission } => {
            if !(alpha.is_finite() && alpha >= 0.0) {
                return Err(("alpha", format!("{alpha} must be finite and non-negative")));
            }
            (Surface::Conductor { specular: reflectance(specular, "specular")?, alpha }, emission)
        }
        MaterialDescription::Dielectric { ior, emission } => {
            if !(ior.is_finite() && ior > 0.0) {
                return Err(("ior", format!("{ior} must be finite and positive")));
            }
            (Surface::Dielectric { ior }, emission)
        }
    };
    let emission = Vec3::from(emission.unwrap_or([0.0; 3]));
    if !is_valid_radiance(emission) {
        return Err(("emission", format!("{emission:?} must be finite and non-negative radiance")));
    }
    Ok(Material { surface, emission })
}

type Geometry<'a> = (&'a str, Vec<Vec3>, Vec<[u32; 3]>);

fn shape_geometry<'a>(
    shape: &'a ShapeDescription,
    folder: &Path,
    path: &Path,
    index: usize,
) -> Result<Geometry<'a>, SceneError> {
    let error = |field: &str, message: String| SceneError::new(path, format!("shapes[{index}].{field}"), message);
    match shape {
        ShapeDescription::Mesh { file, material, transform } => {
            let mesh = mesh::load_mesh(&folder.join(file), path, &format!("shapes[{index}].file"))?;
            let positions = match transform {
                None => mesh.positions,
                Some(rows) => {
                    let matrix = Mat4::from_cols_array_2d(rows).transpose();
                    let determinant = matrix.determinant();
                    if !matrix.is_finite() || determinant == 0.0 || !determinant.is_finite() {
                        return Err(error("transform", "must be finite and invertible".into()));
                    }
                    mesh.positions.iter().map(|&p| matrix.transform_point3(p)).collect()
                }
            };
            if positions.iter().any(|p| !p.is_finite()) {
                return Err(error("transform", "moves a vertex to infinity".into()));
            }
            Ok((material, positions, mesh.triangles))
        }
        ShapeDescription::Quad { corners, material } => {
            let positions: Vec<Vec3> = corners.iter().map(|&c| Vec3::from(c)).collect();
            if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
                return Err(error(&format!("corners[{i}]"), "must be finite".into()));
            }
            Ok((material, positions, vec![[0, 1, 2], [0, 2, 3]]))
        }
        ShapeDescription::Triangles { positions, indices, material } => {
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
            let faces = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            Ok((material, positions, faces))
        }
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
        EnvironmentDescription::Image { file, scale, sun } => {
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
            let texels = image.pixels.iter().map(|&p| p * scale).collect();
            (Sky::Image(LatLongMap::new(image.width, image.height, texels)), sun)
        }
    };
    let sun = match sun {
        Some(sun) => Some(build_sun(sun, path)?),
        None => None,
    };
    Ok(Environment::new(sky, sun))
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
