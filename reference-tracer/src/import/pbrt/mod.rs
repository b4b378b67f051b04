//! A pbrt-v3 reader for the subset real scenes use: Film, a perspective Camera (field of
//! view along the shorter image axis), LookAt / Transform / ConcatTransform / Scale /
//! Translate / Rotate / Identity, AttributeBegin/End, TransformBegin/End,
//! ReverseOrientation, Texture (imagemap, checkerboard, constant), Material /
//! MakeNamedMaterial / NamedMaterial (matte, metal, glass, mirror, plastic, substrate,
//! and Bitterli's `metal_tex`), AreaLightSource diffuse, LightSource infinite, Shape
//! trianglemesh / plymesh, ObjectBegin/End and ObjectInstance (flattened), Include.
//!
//! The crate `pbrt4` parses pbrt-v4 files; pbrt-v3 differs (`PixelFilter` and
//! `WorldEnd` among others) and its errors carry no line, so the tokenizer here is
//! the project's own: quoted strings, numbers and names, brackets, `#` comments.

mod parameters;
mod tokens;
mod translate;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use super::{error_at, Imported};
use crate::scene::{SceneDescription, SceneError};
use parameters::{parse_parameters, Parameters, Values};
use tokens::{tokenize, Token, Tokens};

/// A texture's optional (u, v) scale and offset.
type UvTransform = (Option<[f32; 2]>, Option<[f32; 2]>);

/// The graphics state AttributeBegin saves.
#[derive(Clone, Debug)]
struct Attributes {
    transform: Mat4,
    material: Option<String>,
    /// Emitted radiance of the area light in effect.
    area_light: Option<[f32; 3]>,
    reverse_orientation: bool,
}

/// A shape, kept until instanced when inside ObjectBegin/End.
#[derive(Clone, Debug)]
struct ObjectShape {
    shape: ShapeSource,
    material: String,
    transform: Mat4,
    flip: bool,
}

/// Where a shape's triangles come from.
#[derive(Clone, Debug)]
enum ShapeSource {
    Inline { positions: Vec<Vec3>, indices: Vec<u32>, normals: Option<Vec<Vec3>>, uvs: Option<Vec<[f32; 2]>> },
    Ply { file: String, has_normals: bool },
}

struct Reader {
    /// The file being read (an included one while inside it).
    file: PathBuf,
    folder: PathBuf,
    description: SceneDescription,
    warnings: Vec<String>,
    /// Ignored directives, by name, with how often.
    skipped: Vec<(String, usize)>,
    attributes: Attributes,
    stack: Vec<(Attributes, bool)>,
    named_coordinate_systems: HashMap<String, Mat4>,
    camera_to_world: Option<(Mat4, Parameters)>,
    film: Option<Parameters>,
    in_world: bool,
    objects: HashMap<String, Vec<ObjectShape>>,
    current_object: Option<(String, Vec<ObjectShape>)>,
    /// Materials made emissive for an area light, by (material, radiance bits).
    emissive_variants: HashMap<(String, [u32; 3]), String>,
    include_depth: usize,
}

/// Reads the pbrt-v3 scene `text` of `file`.
pub fn read(file: &Path, text: &str) -> Result<Imported, SceneError> {
    let folder = file.parent().unwrap_or(Path::new(".")).to_path_buf();
    let description = SceneDescription {
        format: 1,
        camera: crate::scene::CameraDescription {
            eye: [0.0; 3],
            target: [0.0, 0.0, 1.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: Some(90.0),
            fov_x_deg: None,
            width: 1,
            height: 1,
            mirrored: false,
            keyframes: Vec::new(),
        },
        textures: Default::default(),
        materials: Default::default(),
        shapes: Vec::new(),
        environment: None,
    };
    let mut reader = Reader {
        file: file.to_path_buf(),
        folder,
        description,
        warnings: Vec::new(),
        skipped: Vec::new(),
        attributes: Attributes {
            transform: Mat4::IDENTITY,
            material: None,
            area_light: None,
            reverse_orientation: false,
        },
        stack: Vec::new(),
        named_coordinate_systems: HashMap::new(),
        camera_to_world: None,
        film: None,
        in_world: false,
        objects: HashMap::new(),
        current_object: None,
        emissive_variants: HashMap::new(),
        include_depth: 0,
    };
    reader.run(file, text)?;
    reader.finish()
}

fn vec3(values: &[f32]) -> Vec3 {
    Vec3::new(values[0], values[1], values[2])
}

/// pbrt's `TrowbridgeReitzDistribution::RoughnessToAlpha` (for `remaproughness true`).
fn roughness_to_alpha(roughness: f32) -> f32 {
    let x = roughness.max(1e-3).ln();
    1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x * x * x + 0.000640711 * x * x * x * x
}

impl Reader {
    fn error(&self, line: usize, message: impl Into<String>) -> SceneError {
        error_at(&self.file, line, message)
    }

    fn skip(&mut self, directive: &str) {
        match self.skipped.iter_mut().find(|(name, _)| name == directive) {
            Some((_, count)) => *count += 1,
            None => self.skipped.push((directive.to_string(), 1)),
        }
    }

    fn quoted(&self, tokens: &mut Tokens, what: &str) -> Result<String, SceneError> {
        match tokens.take() {
            Some((Token::Quoted(s), _)) => Ok(s),
            _ => Err(self.error(tokens.line(), format!("{what}: expected a quoted string"))),
        }
    }

    fn numbers(&self, tokens: &mut Tokens, count: usize, what: &str) -> Result<Vec<f32>, SceneError> {
        let bracketed = matches!(tokens.peek(), Some((Token::Open, _)));
        if bracketed {
            tokens.take();
        }
        let mut values = Vec::with_capacity(count);
        for _ in 0..count {
            match tokens.take() {
                Some((Token::Word(w), line)) => match w.parse::<f32>() {
                    Ok(v) if v.is_finite() => values.push(v),
                    _ => return Err(self.error(line, format!("{what}: \"{w}\" is not a finite number"))),
                },
                _ => return Err(self.error(tokens.line(), format!("{what} takes {count} numbers"))),
            }
        }
        if bracketed && !matches!(tokens.take(), Some((Token::Close, _))) {
            return Err(self.error(tokens.line(), format!("{what}: expected `]` after {count} numbers")));
        }
        Ok(values)
    }

    fn run(&mut self, file: &Path, text: &str) -> Result<(), SceneError> {
        let mut tokens = tokenize(file, text)?;
        while let Some((token, line)) = tokens.take() {
            let Token::Word(directive) = token else {
                return Err(self.error(line, format!("expected a directive, found {token:?}")));
            };
            self.directive(&directive, line, &mut tokens)?;
        }
        Ok(())
    }

    fn directive(&mut self, directive: &str, line: usize, tokens: &mut Tokens) -> Result<(), SceneError> {
        match directive {
            "Identity" => self.attributes.transform = Mat4::IDENTITY,
            "Translate" => {
                let v = self.numbers(tokens, 3, "Translate")?;
                self.attributes.transform *= Mat4::from_translation(vec3(&v));
            }
            "Scale" => {
                let v = self.numbers(tokens, 3, "Scale")?;
                self.attributes.transform *= Mat4::from_scale(vec3(&v));
            }
            "Rotate" => {
                let v = self.numbers(tokens, 4, "Rotate")?;
                let axis = vec3(&v[1..]).try_normalize().ok_or_else(|| self.error(line, "Rotate: zero axis"))?;
                self.attributes.transform *= Mat4::from_axis_angle(axis, v[0].to_radians());
            }
            "LookAt" => {
                let v = self.numbers(tokens, 9, "LookAt")?;
                let (eye, look, up) = (vec3(&v[0..3]), vec3(&v[3..6]), vec3(&v[6..9]));
                let forward = (look - eye).try_normalize().ok_or_else(|| self.error(line, "LookAt: eye = target"))?;
                let right = up.normalize_or_zero().cross(forward).try_normalize();
                let right = right.ok_or_else(|| self.error(line, "LookAt: up is parallel to the view"))?;
                let new_up = forward.cross(right);
                // pbrt's LookAt is world-to-camera: the inverse of (right, up, forward, eye).
                let camera_to_world =
                    Mat4::from_cols(right.extend(0.0), new_up.extend(0.0), forward.extend(0.0), eye.extend(1.0));
                self.attributes.transform *= camera_to_world.inverse();
            }
            "Transform" | "ConcatTransform" => {
                let v = self.numbers(tokens, 16, directive)?;
                // pbrt writes matrices column by column.
                let m = Mat4::from_cols_slice(&v);
                if directive == "Transform" {
                    self.attributes.transform = m;
                } else {
                    self.attributes.transform *= m;
                }
            }
            "CoordinateSystem" => {
                let name = self.quoted(tokens, directive)?;
                self.named_coordinate_systems.insert(name, self.attributes.transform);
            }
            "CoordSysTransform" => {
                let name = self.quoted(tokens, directive)?;
                self.attributes.transform = *self
                    .named_coordinate_systems
                    .get(&name)
                    .ok_or_else(|| self.error(line, format!("unknown coordinate system \"{name}\"")))?;
            }
            "ReverseOrientation" => self.attributes.reverse_orientation = !self.attributes.reverse_orientation,
            "Camera" => {
                let kind = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                if kind != "perspective" {
                    return Err(self.error(line, format!("camera \"{kind}\" is not supported (perspective only)")));
                }
                for unsupported in ["screenwindow", "frameaspectratio", "lensradius"] {
                    if parameters
                        .find(unsupported)
                        .is_some_and(|p| p.name != "lensradius" || p.values != Values::Numbers(vec![0.0]))
                    {
                        return Err(self.error(line, format!("camera parameter `{unsupported}` is not supported")));
                    }
                }
                let camera_to_world = self.attributes.transform.inverse();
                if !camera_to_world.is_finite() {
                    return Err(self.error(line, "the camera transform is not invertible"));
                }
                self.named_coordinate_systems.insert("camera".into(), camera_to_world);
                self.camera_to_world = Some((camera_to_world, parameters));
            }
            "Film" => {
                let _kind = self.quoted(tokens, directive)?;
                self.film = Some(parse_parameters(&self.file, tokens)?);
            }
            "Sampler" | "PixelFilter" | "Integrator" | "Accelerator" | "SurfaceIntegrator" | "VolumeIntegrator" => {
                let _ = self.quoted(tokens, directive)?;
                parse_parameters(&self.file, tokens)?;
                self.skip(directive);
            }
            "WorldBegin" => {
                self.in_world = true;
                self.attributes.transform = Mat4::IDENTITY;
                self.named_coordinate_systems.insert("world".into(), Mat4::IDENTITY);
            }
            "WorldEnd" => {}
            "AttributeBegin" | "TransformBegin" => {
                self.stack.push((self.attributes.clone(), directive == "TransformBegin"));
            }
            "AttributeEnd" | "TransformEnd" => {
                let Some((saved, transform_only)) = self.stack.pop() else {
                    return Err(self.error(line, format!("{directive} without a matching begin")));
                };
                if transform_only != (directive == "TransformEnd") {
                    return Err(self.error(line, format!("{directive} closes a block it did not open")));
                }
                if transform_only {
                    self.attributes.transform = saved.transform;
                } else {
                    self.attributes = saved;
                }
            }
            "Texture" => {
                let name = self.quoted(tokens, directive)?;
                let _value_type = self.quoted(tokens, directive)?;
                let class = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                let texture = self.texture(&class, &parameters, line)?;
                self.description.textures.insert(name, texture);
            }
            "MakeNamedMaterial" => {
                let name = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                let kind = parameters
                    .string(&self.file, "type")?
                    .ok_or_else(|| self.error(line, format!("material \"{name}\" has no \"string type\"")))?
                    .to_string();
                let material = self.material(&kind, &parameters, line)?;
                self.description.materials.insert(name, material);
            }
            "Material" => {
                let kind = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                let material = self.material(&kind, &parameters, line)?;
                let name = format!("material-line-{line}");
                self.description.materials.insert(name.clone(), material);
                self.attributes.material = Some(name);
            }
            "NamedMaterial" => {
                let name = self.quoted(tokens, directive)?;
                if !self.description.materials.contains_key(&name) {
                    return Err(self.error(line, format!("unknown material \"{name}\"")));
                }
                self.attributes.material = Some(name);
            }
            "AreaLightSource" => {
                let kind = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                if kind != "diffuse" {
                    return Err(self.error(line, format!("area light \"{kind}\" is not supported (diffuse only)")));
                }
                if parameters.boolean(&self.file, "twosided", false)? {
                    return Err(self.error(line, "two-sided area lights are not supported"));
                }
                let radiance = parameters.rgb(&self.file, "L")?.unwrap_or([1.0; 3]);
                let scale = parameters.float(&self.file, "scale", 1.0)?;
                self.attributes.area_light = Some(radiance.map(|c| c * scale));
            }
            "LightSource" => {
                let kind = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                self.light_source(&kind, &parameters, line)?;
            }
            "Shape" => {
                let kind = self.quoted(tokens, directive)?;
                let parameters = parse_parameters(&self.file, tokens)?;
                self.shape(&kind, &parameters, line)?;
            }
            "ObjectBegin" => {
                let name = self.quoted(tokens, directive)?;
                if self.current_object.is_some() {
                    return Err(self.error(line, "ObjectBegin inside another object"));
                }
                self.stack.push((self.attributes.clone(), false));
                self.current_object = Some((name, Vec::new()));
            }
            "ObjectEnd" => {
                let Some((name, shapes)) = self.current_object.take() else {
                    return Err(self.error(line, "ObjectEnd without ObjectBegin"));
                };
                self.objects.insert(name, shapes);
                if let Some((saved, _)) = self.stack.pop() {
                    self.attributes = saved;
                }
            }
            "ObjectInstance" => {
                let name = self.quoted(tokens, directive)?;
                let shapes = self
                    .objects
                    .get(&name)
                    .cloned()
                    .ok_or_else(|| self.error(line, format!("unknown object \"{name}\"")))?;
                let instance = self.attributes.transform;
                for shape in shapes {
                    self.emit(ObjectShape { transform: instance * shape.transform, ..shape });
                }
            }
            "Include" | "Import" => {
                let name = self.quoted(tokens, directive)?;
                let path = self.folder.join(&name);
                if self.include_depth >= 16 {
                    return Err(self.error(line, "Include nested more than 16 deep"));
                }
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| self.error(line, format!("cannot read {}: {e}", path.display())))?;
                self.include_depth += 1;
                // Errors inside name the included file.
                let file = std::mem::replace(&mut self.file, path.clone());
                let result = self.run(&path, &text);
                self.file = file;
                self.include_depth -= 1;
                result?;
            }
            "MakeNamedMedium" | "MediumInterface" => {
                return Err(self.error(line, format!("{directive}: participating media are not supported")));
            }
            other => return Err(self.error(line, format!("unknown directive `{other}`"))),
        }
        Ok(())
    }
}
