//! Readers for other renderers' scene files — a pbrt-v3 subset ([`pbrt`]) and a Mitsuba
//! 0.5 XML subset ([`mitsuba`]) — chosen by extension. Each produces the project's own
//! [`SceneDescription`], so what it read can be written out as JSON (`lodestar
//! convert`) and is checked and built exactly like a JSON scene.
//!
//! Errors name the file and line. Directives that change nothing the tracer renders
//! (integrator, sampler, filter settings) are skipped and listed as warnings; anything
//! else unknown is an error, so a scene never renders silently wrong.

mod inline_mtl;
pub mod mitsuba;
pub mod pbrt;
mod primitives;

pub use inline_mtl::inline_mtl_meshes;

use std::path::Path;

use glam::{Mat4, Vec3};

use crate::scene::{CameraDescription, Scene, SceneDescription, SceneError};

/// A scene read from a foreign format, with what was skipped or approximated.
#[derive(Clone, Debug)]
pub struct Imported {
    /// The scene in the project's format; relative paths resolve against the folder of
    /// the file it was read from.
    pub description: SceneDescription,
    /// What the reader skipped or approximated, for the user to see.
    pub warnings: Vec<String>,
}

/// The scene formats the tracer reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    /// The project's JSON (SCENE_FORMAT.md).
    Json,
    /// pbrt-v3 (`.pbrt`).
    Pbrt,
    /// Mitsuba 0.5 XML (`.xml`).
    Mitsuba,
}

impl SceneFormat {
    /// The format of `path`, by its extension.
    pub fn of(path: &Path) -> Result<Self, SceneError> {
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("json") => Ok(SceneFormat::Json),
            Some("pbrt") => Ok(SceneFormat::Pbrt),
            Some("xml") => Ok(SceneFormat::Mitsuba),
            _ => Err(SceneError::new(path, "", "unknown scene format (expected .json, .pbrt or .xml)")),
        }
    }
}

// `Scene::load` dispatches to the readers here, so it lives beside them: the scene
// module builds scenes from descriptions and knows no file format but its own JSON.
impl Scene {
    /// Reads and checks a scene file: the project's JSON, or by its extension a pbrt-v3
    /// (`.pbrt`) or Mitsuba (`.xml`) scene. Every error names the file and where in it.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        match SceneFormat::of(path)? {
            SceneFormat::Json => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| SceneError::new(path, "", format!("cannot read: {e}")))?;
                Self::from_json(path, &text)
            }
            _ => {
                let imported = import(path)?;
                let mut scene = Self::from_description(path, imported.description)?;
                scene.warnings.splice(0..0, imported.warnings);
                Ok(scene)
            }
        }
    }
}

/// Reads a pbrt or Mitsuba file.
pub fn import(path: &Path) -> Result<Imported, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::new(path, "", format!("cannot read: {e}")))?;
    match SceneFormat::of(path)? {
        SceneFormat::Pbrt => pbrt::read(path, &text),
        SceneFormat::Mitsuba => mitsuba::read(path, &text),
        SceneFormat::Json => Err(SceneError::new(path, "", "a JSON scene needs no import")),
    }
}

/// Reads the pbrt or Mitsuba scene `input`, checks that it builds, and writes it to
/// `output` in the project's JSON format, with every file it names made relative to
/// `output`'s folder. Returns what the reader skipped or approximated.
pub fn convert(input: &Path, output: &Path) -> Result<Vec<String>, SceneError> {
    let Imported { description, warnings } = import(input)?;
    write_json(input, description, output)?;
    Ok(warnings)
}

/// Writes the scene `input` (JSON, pbrt or Mitsuba) to `output` as JSON in which every
/// shape names its material: meshes that take their OBJ's MTL materials are written
/// inline ([`inline_mtl_meshes`]). For a renderer that reads the project's JSON but not
/// MTL files (the Mitsuba peer). Returns what a foreign reader skipped or approximated.
pub fn write_self_contained_json(input: &Path, output: &Path) -> Result<Vec<String>, SceneError> {
    let (mut description, warnings) = match SceneFormat::of(input)? {
        SceneFormat::Json => {
            let text =
                std::fs::read_to_string(input).map_err(|e| SceneError::new(input, "", format!("cannot read: {e}")))?;
            (SceneDescription::from_json(input, &text)?, Vec::new())
        }
        _ => {
            let Imported { description, warnings } = import(input)?;
            (description, warnings)
        }
    };
    // The scene as written must build (the loader names a face without a material), and
    // so must the one written inline (`write_json` checks it).
    Scene::from_description(input, description.clone())?;
    inline_mtl_meshes(&mut description, input)?;
    write_json(input, description, output)?;
    Ok(warnings)
}

/// Checks that `description` (read from `input`) builds and writes it to `output` as
/// JSON, every file it names made relative to `output`'s folder.
fn write_json(input: &Path, mut description: SceneDescription, output: &Path) -> Result<(), SceneError> {
    Scene::from_description(input, description.clone())?;
    let from = input.parent().unwrap_or(Path::new("."));
    let to = output.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let rebase = |file: &mut String| {
        *file = relative_path(&from.join(&*file), to).to_string_lossy().into_owned();
    };
    for shape in &mut description.shapes {
        if let crate::scene::ShapeDescription::Mesh { file, .. } = shape {
            rebase(file);
        }
    }
    for texture in description.textures.values_mut() {
        if let crate::scene::TextureDescription::Image { file, .. } = texture {
            rebase(file);
        }
    }
    if let Some(crate::scene::EnvironmentDescription::Image { file, .. }) = &mut description.environment {
        rebase(file);
    }
    let json = serde_json::to_string_pretty(&description)
        .map_err(|e| SceneError::new(output, "", format!("cannot encode the scene: {e}")))?;
    std::fs::write(output, json + "\n").map_err(|e| SceneError::new(output, "", format!("cannot write: {e}")))
}

/// An error at `line` of `file`.
pub(crate) fn error_at(file: &Path, line: usize, message: impl Into<String>) -> SceneError {
    SceneError::new(file, format!("line {line}"), message)
}

/// The project's camera for a camera-to-world matrix whose camera looks along +z with
/// +y up, and whose image's right is `image_right` in camera space (pbrt: +x; Mitsuba:
/// −x), with a field of view of `fov_deg` along the horizontal (`horizontal`) or the
/// vertical image axis.
pub(crate) fn camera_from_matrix(
    camera_to_world: Mat4,
    image_right: Vec3,
    (fov_deg, horizontal): (f32, bool),
    width: u32,
    height: u32,
) -> Option<CameraDescription> {
    let eye = camera_to_world.transform_point3(Vec3::ZERO);
    let forward = camera_to_world.transform_vector3(Vec3::Z).try_normalize()?;
    let up = camera_to_world.transform_vector3(Vec3::Y).try_normalize()?;
    let right = camera_to_world.transform_vector3(image_right);
    let mirrored = right.dot(forward.cross(up)) < 0.0;
    Some(CameraDescription {
        eye: eye.to_array(),
        target: (eye + forward).to_array(),
        up: up.to_array(),
        fov_y_deg: (!horizontal).then_some(fov_deg),
        fov_x_deg: horizontal.then_some(fov_deg),
        width,
        height,
        mirrored,
        keyframes: Vec::new(),
    })
}

/// A 4×4 matrix as the scene format writes it: row-major rows.
pub(crate) fn rows_of(matrix: Mat4) -> [[f32; 4]; 4] {
    matrix.transpose().to_cols_array_2d()
}

/// `path` relative to `base` (a folder), for file names written into a scene that
/// lives in `base`; unchanged when no relative path exists (different roots).
pub fn relative_path(path: &Path, base: &Path) -> std::path::PathBuf {
    use std::path::{Component, PathBuf};
    let absolute = |p: &Path| {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            std::env::current_dir().map(|d| d.join(p)).unwrap_or_else(|_| p.to_path_buf())
        }
    };
    let normal = |p: PathBuf| {
        let mut parts: Vec<std::ffi::OsString> = Vec::new();
        for c in p.components() {
            match c {
                Component::CurDir => {}
                Component::ParentDir if parts.last().is_some_and(|last| last != "/" && last != "..") => {
                    parts.pop();
                }
                other => parts.push(other.as_os_str().to_os_string()),
            }
        }
        parts
    };
    let (path_parts, base_parts) = (normal(absolute(path)), normal(absolute(base)));
    if path_parts.first() != base_parts.first() {
        return path.to_path_buf();
    }
    let common = path_parts.iter().zip(&base_parts).take_while(|(a, b)| a == b).count();
    let mut relative = PathBuf::new();
    for _ in common..base_parts.len() {
        relative.push("..");
    }
    for part in &path_parts[common..] {
        relative.push(part);
    }
    relative
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_climb_and_descend() {
        let p = relative_path(Path::new("/a/b/scene/textures/x.jpg"), Path::new("/a/b/out"));
        assert_eq!(p, Path::new("../scene/textures/x.jpg"));
        assert_eq!(relative_path(Path::new("/a/x.obj"), Path::new("/a")), Path::new("x.obj"));
        assert_eq!(relative_path(Path::new("/a/./b/../x.obj"), Path::new("/a/c")), Path::new("../x.obj"));
    }

    #[test]
    fn cameras_from_matrices_keep_the_image_unmirrored_or_say_so() {
        // Mitsuba's lookat from z = 5 towards the origin, +y up: its +x (the image's left)
        // is up × forward = −x, so the image's right is +x.
        let mitsuba = Mat4::from_cols(
            Vec3::NEG_X.extend(0.0),
            Vec3::Y.extend(0.0),
            Vec3::NEG_Z.extend(0.0),
            Vec3::new(0.0, 0.0, 5.0).extend(1.0),
        );
        let camera = camera_from_matrix(mitsuba, Vec3::NEG_X, (40.0, false), 64, 64).unwrap();
        assert!(!camera.mirrored);
        assert!((Vec3::from(camera.target) - Vec3::new(0.0, 0.0, 4.0)).length() < 1e-5);
        // The same matrix read as pbrt's (+x is the image's right) is mirrored.
        assert!(camera_from_matrix(mitsuba, Vec3::X, (40.0, true), 64, 64).unwrap().mirrored);
    }
}
