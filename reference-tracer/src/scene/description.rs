//! The scene file as written (SCENE_FORMAT.md, version 1): serde types that reject
//! unknown keys, so a typo is an error with its path instead of a silent default. The
//! scene readers for other formats (pbrt-v3, Mitsuba) produce these same types, and
//! `lodestar convert` writes them back out as JSON.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::SceneError;

/// The whole file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDescription {
    /// Format version; 1.
    pub format: u32,
    /// The camera.
    pub camera: CameraDescription,
    /// Image textures and procedural patterns by name, referenced by materials.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub textures: BTreeMap<String, TextureDescription>,
    /// Materials by name.
    pub materials: BTreeMap<String, MaterialDescription>,
    /// Geometry.
    pub shapes: Vec<ShapeDescription>,
    /// Light from infinitely far away; absent means black.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentDescription>,
}

impl SceneDescription {
    /// Parses the JSON scene `text` read from `path`; an error names where in it.
    pub fn from_json(path: &Path, text: &str) -> Result<Self, SceneError> {
        let deserializer = &mut serde_json::Deserializer::from_str(text);
        serde_path_to_error::deserialize(deserializer).map_err(|e| {
            let location = match e.path().to_string().as_str() {
                "." => String::new(),
                p => p.to_string(),
            };
            let inner = e.inner();
            SceneError::new(path, location, format!("{inner} (line {}, column {})", inner.line(), inner.column()))
        })
    }
}

/// A pinhole camera.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDescription {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up direction.
    pub up: [f32; 3],
    /// Vertical field of view, degrees (give this or `fov_x_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_y_deg: Option<f32>,
    /// Horizontal field of view, degrees (instead of `fov_y_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_x_deg: Option<f32>,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The image's right is up × forward instead of forward × up (pbrt's left-handed
    /// camera): the picture is mirrored left to right.
    #[serde(default, skip_serializing_if = "is_false")]
    pub mirrored: bool,
    /// An animation's views (`lodestar render --frames N`): at least two, spread evenly
    /// over the frames (the first at frame 0, the last at frame N − 1) and joined by
    /// straight lines; `up`, the field of view and the size stay those above. Absent or
    /// empty: every frame shows `eye` → `target`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keyframes: Vec<CameraKeyframe>,
}

/// One view of a camera animation.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraKeyframe {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
}

fn is_false(value: &bool) -> bool {
    !*value
}

/// A texture: RGB values over the (u, v) parameters of a surface, (0, 0) at an image's
/// bottom-left corner.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum TextureDescription {
    /// An image (PNG, JPEG, EXR, HDR), bilinearly filtered, repeating outside [0, 1]².
    Image {
        /// Path relative to the scene file's folder.
        file: String,
        /// How 8-bit values map to reflectance: `srgb` (the default for 8-bit images)
        /// or `linear`. Floating-point images are always linear.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        encoding: Option<TextureEncoding>,
        /// Multiplies (u, v) before the lookup, [su, sv].
        #[serde(default, skip_serializing_if = "Option::is_none")]
        uv_scale: Option<[f32; 2]>,
        /// Added to (u, v) after scaling, [du, dv].
        #[serde(default, skip_serializing_if = "Option::is_none")]
        uv_offset: Option<[f32; 2]>,
    },
    /// Squares alternating between two colours: `even` where ⌊s⌋ + ⌊t⌋ is even, with
    /// (s, t) = uv_scale · (u, v) + uv_offset.
    Checkerboard {
        /// Colour of the even squares, in [0, 1]³.
        even: [f32; 3],
        /// Colour of the odd squares, in [0, 1]³.
        odd: [f32; 3],
        /// [su, sv]: squares per unit of u and v.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        uv_scale: Option<[f32; 2]>,
        /// [du, dv].
        #[serde(default, skip_serializing_if = "Option::is_none")]
        uv_offset: Option<[f32; 2]>,
    },
}

/// How an 8-bit image's values are decoded.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum TextureEncoding {
    /// The sRGB transfer curve (most photographs and paintings).
    Srgb,
    /// Values are linear already (masks, data).
    Linear,
}

/// A material; any may emit, and any but glass may carry an opacity texture.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MaterialDescription {
    /// Lambertian.
    Diffuse {
        /// Reflectance in \[0, 1\]³; multiplies `albedo_texture` (default 1 with one).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        albedo: Option<[f32; 3]>,
        /// A texture name: reflectance per surface point.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        albedo_texture: Option<String>,
        /// A texture name: opacity in [0, 1] (its luminance); 0 lets light pass.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        opacity_texture: Option<String>,
        /// Radiance leaving the front face.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<[f32; 3]>,
    },
    /// GGX microfacet reflection: Fresnel of a complex index of refraction when `eta`
    /// and `k` are given, none otherwise.
    Conductor {
        /// Reflectance scale in \[0, 1\]³ (default 1); multiplies `specular_texture`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        specular: Option<[f32; 3]>,
        /// A texture name: reflectance scale per surface point.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        specular_texture: Option<String>,
        /// GGX roughness α (not squared); 0 is a mirror.
        alpha: f32,
        /// Real part of the index of refraction, per RGB channel.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        eta: Option<[f32; 3]>,
        /// Imaginary part (absorption), per RGB channel.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        k: Option<[f32; 3]>,
        /// A texture name: opacity in [0, 1].
        #[serde(default, skip_serializing_if = "Option::is_none")]
        opacity_texture: Option<String>,
        /// Radiance leaving the front face.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<[f32; 3]>,
    },
    /// Smooth glass.
    Dielectric {
        /// Index of refraction relative to the outside.
        ior: f32,
        /// Radiance leaving the front face.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<[f32; 3]>,
    },
    /// A thin smooth glass sheet (a window pane): Fresnel reflection including the
    /// inter-reflections inside the sheet; the rest passes straight through.
    ThinDielectric {
        /// Index of refraction of the sheet relative to the outside.
        ior: f32,
        /// Radiance leaving the front face.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<[f32; 3]>,
    },
    /// A diffuse base under a GGX dielectric coat (Mitsuba's roughplastic): specular
    /// reflection with Fresnel, and diffuse light that entered and left through the coat.
    Plastic {
        /// Base reflectance in \[0, 1\]³; multiplies `albedo_texture` (default 1 with one).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        albedo: Option<[f32; 3]>,
        /// A texture name: base reflectance per surface point.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        albedo_texture: Option<String>,
        /// Scale of the coat's reflection in \[0, 1\] (default 1).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        specular: Option<f32>,
        /// Index of refraction of the coat (default 1.5).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ior: Option<f32>,
        /// GGX roughness α of the coat; values under 0.001 are raised to it.
        alpha: f32,
        /// A texture name: opacity in [0, 1].
        #[serde(default, skip_serializing_if = "Option::is_none")]
        opacity_texture: Option<String>,
        /// Radiance leaving the front face.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<[f32; 3]>,
    },
}

impl MaterialDescription {
    /// The same material emitting `radiance` from its front face (an area light).
    pub fn emitting(&self, radiance: [f32; 3]) -> Self {
        let mut emitting = self.clone();
        match &mut emitting {
            MaterialDescription::Diffuse { emission, .. }
            | MaterialDescription::Conductor { emission, .. }
            | MaterialDescription::Dielectric { emission, .. }
            | MaterialDescription::ThinDielectric { emission, .. }
            | MaterialDescription::Plastic { emission, .. } => *emission = Some(radiance),
        }
        emitting
    }
}

/// A piece of geometry with one material.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeDescription {
    /// An OBJ or PLY file.
    Mesh {
        /// Path relative to the scene file's folder.
        file: String,
        /// Material name; absent for an OBJ whose MTL file gives each face its material.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        material: Option<String>,
        /// Optional 4×4 row-major transform.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        transform: Option<[[f32; 4]; 4]>,
        /// Ignore the file's vertex normals (flat shading).
        #[serde(default, skip_serializing_if = "is_false")]
        face_normals: bool,
        /// Reverse every face's winding (and so which side is its front).
        #[serde(default, skip_serializing_if = "is_false")]
        flip: bool,
        /// Each face's front is the side its vertex normals point to (as pbrt and
        /// Mitsuba decide), not its winding; applied before `flip`.
        #[serde(default, skip_serializing_if = "is_false")]
        front_from_normals: bool,
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
        /// Per-vertex shading normals (any length > 0), parallel to `positions`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        normals: Option<Vec<[f32; 3]>>,
        /// Per-vertex texture coordinates, parallel to `positions`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        uvs: Option<Vec<[f32; 2]>>,
        /// Each face's front is the side its vertex normals point to, not its winding.
        #[serde(default, skip_serializing_if = "is_false")]
        front_from_normals: bool,
        /// Material name.
        material: String,
    },
}

/// Environment light.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum EnvironmentDescription {
    /// Uniform radiance.
    Constant {
        /// Radiance.
        radiance: [f32; 3],
        /// A sun on top of it.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sun: Option<SunDescription>,
    },
    /// A lat-long image.
    Image {
        /// .exr, .hdr or .pfm, relative to the scene file's folder.
        file: String,
        /// Radiance multiplier.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        scale: Option<f32>,
        /// A 3×3 row-major rotation taking the map's directions to the world's.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        rotation: Option<[[f32; 3]; 3]>,
        /// A sun on top of it.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sun: Option<SunDescription>,
    },
}

/// A sun: a disk of uniform radiance far away, sampled apart from the sky.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SunDescription {
    /// Towards the sun's centre (any length > 0).
    pub direction: [f32; 3],
    /// Angular radius, degrees, in (0, 90].
    pub angular_radius_deg: f32,
    /// Radiance inside the disk.
    pub radiance: [f32; 3],
}
