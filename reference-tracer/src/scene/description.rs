//! The scene file as written (SCENE_FORMAT.md, version 1): serde types that reject
//! unknown keys, so a typo is an error with its path instead of a silent default.

use std::collections::BTreeMap;

use serde::Deserialize;

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDescription {
    /// Format version; 1.
    pub format: u32,
    /// The camera.
    pub camera: CameraDescription,
    /// Materials by name.
    pub materials: BTreeMap<String, MaterialDescription>,
    /// Geometry.
    pub shapes: Vec<ShapeDescription>,
    /// Light from infinitely far away; absent means black.
    #[serde(default)]
    pub environment: Option<EnvironmentDescription>,
}

/// A pinhole camera.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDescription {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up direction.
    pub up: [f32; 3],
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

/// A material; any may emit.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum MaterialDescription {
    /// Lambertian.
    Diffuse {
        /// Reflectance in \[0, 1\]³.
        albedo: [f32; 3],
        /// Radiance leaving the front face.
        #[serde(default)]
        emission: Option<[f32; 3]>,
    },
    /// GGX microfacet reflection, no Fresnel.
    Conductor {
        /// Reflectance scale in \[0, 1\]³.
        specular: [f32; 3],
        /// GGX roughness α (not squared); 0 is a mirror.
        alpha: f32,
        /// Radiance leaving the front face.
        #[serde(default)]
        emission: Option<[f32; 3]>,
    },
    /// Smooth glass.
    Dielectric {
        /// Index of refraction relative to the outside.
        ior: f32,
        /// Radiance leaving the front face.
        #[serde(default)]
        emission: Option<[f32; 3]>,
    },
}

/// A piece of geometry with one material.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ShapeDescription {
    /// An OBJ or PLY file.
    Mesh {
        /// Path relative to the scene file's folder.
        file: String,
        /// Material name.
        material: String,
        /// Optional 4×4 row-major transform.
        #[serde(default)]
        transform: Option<[[f32; 4]; 4]>,
    },
    /// Four corners, counter-clockwise seen from the front.
    Quad {
        /// The corners.
        corners: [[f32; 3]; 4],
        /// Material name.
        material: String,
    },
    /// Inline triangles.
    Triangles {
        /// Vertex positions.
        positions: Vec<[f32; 3]>,
        /// Three indices per triangle.
        indices: Vec<u32>,
        /// Material name.
        material: String,
    },
}

/// Environment light.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum EnvironmentDescription {
    /// Uniform radiance.
    Constant {
        /// Radiance.
        radiance: [f32; 3],
        /// A sun on top of it.
        #[serde(default)]
        sun: Option<SunDescription>,
    },
    /// A lat-long image.
    Image {
        /// .exr, .hdr or .pfm, relative to the scene file's folder.
        file: String,
        /// Radiance multiplier.
        #[serde(default)]
        scale: Option<f32>,
        /// A sun on top of it.
        #[serde(default)]
        sun: Option<SunDescription>,
    },
}

/// A sun: a disk of uniform radiance far away, sampled apart from the sky.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunDescription {
    /// Towards the sun's centre (any length > 0).
    pub direction: [f32; 3],
    /// Angular radius, degrees, in (0, 90].
    pub angular_radius_deg: f32,
    /// Radiance inside the disk.
    pub radiance: [f32; 3],
}
