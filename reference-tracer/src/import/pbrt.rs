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

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec3};

use super::{camera_from_matrix, error_at, rows_of, Imported};
use crate::scene::{
    ply_has_normals, EnvironmentDescription, MaterialDescription, SceneDescription, SceneError, ShapeDescription,
    TextureDescription, TextureEncoding,
};

/// One token and the line it starts on.
#[derive(Clone, Debug, PartialEq)]
enum Token {
    /// A bare word or number.
    Word(String),
    /// A quoted string, without its quotes.
    Quoted(String),
    Open,
    Close,
}

struct Tokens {
    tokens: Vec<(Token, usize)>,
    next: usize,
}

fn tokenize(file: &Path, text: &str) -> Result<Tokens, SceneError> {
    let mut tokens = Vec::new();
    let mut chars = text.char_indices().peekable();
    let mut line = 1;
    while let Some((_, c)) = chars.next() {
        match c {
            '\n' => line += 1,
            c if c.is_whitespace() => {}
            '#' => {
                for (_, c) in chars.by_ref() {
                    if c == '\n' {
                        line += 1;
                        break;
                    }
                }
            }
            '[' => tokens.push((Token::Open, line)),
            ']' => tokens.push((Token::Close, line)),
            '"' => {
                let start = line;
                let mut value = String::new();
                loop {
                    match chars.next() {
                        None => return Err(error_at(file, start, "unterminated string")),
                        Some((_, '"')) => break,
                        Some((_, '\n')) => return Err(error_at(file, start, "string runs past the end of its line")),
                        Some((_, '\\')) => match chars.next() {
                            Some((_, 'n')) => value.push('\n'),
                            Some((_, 't')) => value.push('\t'),
                            Some((_, c)) => value.push(c),
                            None => return Err(error_at(file, start, "unterminated string")),
                        },
                        Some((_, c)) => value.push(c),
                    }
                }
                tokens.push((Token::Quoted(value), start));
            }
            c => {
                let mut word = String::from(c);
                while let Some(&(_, c)) = chars.peek() {
                    if c.is_whitespace() || matches!(c, '[' | ']' | '"' | '#') {
                        break;
                    }
                    word.push(c);
                    chars.next();
                }
                tokens.push((Token::Word(word), line));
            }
        }
    }
    Ok(Tokens { tokens, next: 0 })
}

impl Tokens {
    fn peek(&self) -> Option<&(Token, usize)> {
        self.tokens.get(self.next)
    }

    fn take(&mut self) -> Option<(Token, usize)> {
        let token = self.tokens.get(self.next).cloned();
        self.next += token.is_some() as usize;
        token
    }

    fn line(&self) -> usize {
        self.tokens.get(self.next.saturating_sub(1)).map_or(1, |t| t.1)
    }
}

/// A parameter's values: numbers, strings or booleans, as written.
#[derive(Clone, Debug, PartialEq)]
enum Values {
    Numbers(Vec<f32>),
    Strings(Vec<String>),
}

/// One `"type name" value…` of a parameter list.
#[derive(Clone, Debug)]
struct Parameter {
    kind: String,
    name: String,
    values: Values,
    /// The line it is written on.
    line: usize,
}

/// A directive's parameter list, with lookups that name the directive's line in errors.
#[derive(Clone, Debug, Default)]
struct Parameters {
    list: Vec<Parameter>,
    line: usize,
}

impl Parameters {
    fn find(&self, name: &str) -> Option<&Parameter> {
        self.list.iter().find(|p| p.name == name)
    }

    fn numbers(&self, file: &Path, name: &str) -> Result<Option<&[f32]>, SceneError> {
        match self.find(name) {
            None => Ok(None),
            Some(Parameter { values: Values::Numbers(v), .. }) => Ok(Some(v)),
            Some(p) => Err(error_at(file, p.line, format!("\"{} {name}\" must hold numbers", p.kind))),
        }
    }

    fn float(&self, file: &Path, name: &str, default: f32) -> Result<f32, SceneError> {
        match self.numbers(file, name)? {
            None => Ok(default),
            Some([v]) => Ok(*v),
            Some(_) => {
                Err(error_at(file, self.find(name).map_or(self.line, |p| p.line), format!("`{name}` takes one number")))
            }
        }
    }

    fn string(&self, file: &Path, name: &str) -> Result<Option<&str>, SceneError> {
        match self.find(name) {
            None => Ok(None),
            Some(Parameter { values: Values::Strings(v), .. }) if v.len() == 1 => Ok(Some(&v[0])),
            Some(p) => Err(error_at(file, p.line, format!("`{name}` takes one string"))),
        }
    }

    fn boolean(&self, file: &Path, name: &str, default: bool) -> Result<bool, SceneError> {
        match self.string(file, name)? {
            None => Ok(default),
            Some("true") => Ok(true),
            Some("false") => Ok(false),
            Some(other) => Err(error_at(file, self.line, format!("`{name}` is \"{other}\", expected true or false"))),
        }
    }

    /// An RGB colour (`rgb`/`color`, or one number for a grey `float`), or a texture's name.
    fn color_or_texture(&self, file: &Path, name: &str) -> Result<Option<ColorOrTexture>, SceneError> {
        let Some(p) = self.find(name) else { return Ok(None) };
        match (p.kind.as_str(), &p.values) {
            ("rgb" | "color", Values::Numbers(v)) if v.len() == 3 => {
                Ok(Some(ColorOrTexture::Color([v[0], v[1], v[2]])))
            }
            ("float", Values::Numbers(v)) if v.len() == 1 => Ok(Some(ColorOrTexture::Color([v[0]; 3]))),
            ("texture", Values::Strings(v)) if v.len() == 1 => Ok(Some(ColorOrTexture::Texture(v[0].clone()))),
            ("spectrum" | "blackbody", _) => Err(error_at(
                file,
                p.line,
                format!("\"{} {name}\": spectral values are not supported; give \"rgb {name}\"", p.kind),
            )),
            _ => Err(error_at(file, p.line, format!("\"{} {name}\" must be an RGB colour or a texture", p.kind))),
        }
    }

    fn rgb(&self, file: &Path, name: &str) -> Result<Option<[f32; 3]>, SceneError> {
        match self.color_or_texture(file, name)? {
            None => Ok(None),
            Some(ColorOrTexture::Color(c)) => Ok(Some(c)),
            Some(ColorOrTexture::Texture(_)) => {
                Err(error_at(file, self.line, format!("`{name}` must be a colour here, not a texture")))
            }
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
enum ColorOrTexture {
    Color([f32; 3]),
    Texture(String),
}

fn parse_parameters(file: &Path, tokens: &mut Tokens) -> Result<Parameters, SceneError> {
    let mut parameters = Parameters { list: Vec::new(), line: tokens.line() };
    while let Some((Token::Quoted(_), _)) = tokens.peek() {
        let Some((Token::Quoted(declaration), line)) = tokens.take() else { unreachable!() };
        let mut words = declaration.split_whitespace();
        let (Some(kind), Some(name), None) = (words.next(), words.next(), words.next()) else {
            return Err(error_at(file, line, format!("parameter \"{declaration}\" is not \"type name\"")));
        };
        let (kind, name) = (kind.to_string(), name.to_string());
        let mut raw = Vec::new();
        match tokens.take() {
            Some((Token::Open, _)) => loop {
                match tokens.take() {
                    Some((Token::Close, _)) => break,
                    Some((Token::Open, l)) => return Err(error_at(file, l, "nested `[`")),
                    Some((token, _)) => raw.push(token),
                    None => return Err(error_at(file, line, format!("`{name}`: unterminated `[`"))),
                }
            },
            Some((token @ (Token::Word(_) | Token::Quoted(_)), _)) => raw.push(token),
            _ => return Err(error_at(file, line, format!("`{name}` has no value"))),
        }
        let numeric = matches!(
            kind.as_str(),
            "float"
                | "integer"
                | "point"
                | "point3"
                | "normal"
                | "normal3"
                | "vector"
                | "vector3"
                | "rgb"
                | "color"
                | "point2"
                | "vector2"
                | "blackbody"
                | "spectrum"
        ) && raw.iter().all(|t| matches!(t, Token::Word(_)));
        let values = if numeric {
            let numbers: Result<Vec<f32>, _> = raw
                .iter()
                .map(|t| match t {
                    Token::Word(w) => w.parse::<f32>().map_err(|_| w.clone()),
                    _ => Err(String::new()),
                })
                .collect();
            Values::Numbers(numbers.map_err(|w| error_at(file, line, format!("`{name}`: \"{w}\" is not a number")))?)
        } else {
            Values::Strings(
                raw.into_iter()
                    .map(|t| match t {
                        Token::Word(w) | Token::Quoted(w) => w,
                        _ => String::new(),
                    })
                    .collect(),
            )
        };
        if let Values::Numbers(v) = &values {
            if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
                return Err(error_at(file, line, format!("`{name}`: {bad} is not finite")));
            }
        }
        parameters.list.push(Parameter { kind, name, values, line });
    }
    Ok(parameters)
}

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

    fn texture(&self, class: &str, p: &Parameters, line: usize) -> Result<TextureDescription, SceneError> {
        let uv_transform = |p: &Parameters| -> Result<UvTransform, SceneError> {
            if let Some(mapping) = p.string(&self.file, "mapping")? {
                if mapping != "uv" {
                    return Err(self.error(line, format!("texture mapping \"{mapping}\" is not supported (uv only)")));
                }
            }
            let scale = [p.float(&self.file, "uscale", 1.0)?, p.float(&self.file, "vscale", 1.0)?];
            let offset = [p.float(&self.file, "udelta", 0.0)?, p.float(&self.file, "vdelta", 0.0)?];
            Ok(((scale != [1.0; 2]).then_some(scale), (offset != [0.0; 2]).then_some(offset)))
        };
        match class {
            "imagemap" => {
                let file = p
                    .string(&self.file, "filename")?
                    .ok_or_else(|| self.error(line, "imagemap without \"string filename\""))?
                    .to_string();
                if p.float(&self.file, "scale", 1.0)? != 1.0 {
                    return Err(self.error(line, "imagemap `scale` is not supported"));
                }
                let (uv_scale, uv_offset) = uv_transform(p)?;
                // pbrt-v3 decodes 8-bit images by sRGB unless told otherwise.
                let encoding = (!p.boolean(&self.file, "gamma", true)?).then_some(TextureEncoding::Linear);
                Ok(TextureDescription::Image { file, encoding, uv_scale, uv_offset })
            }
            "checkerboard" => {
                if p.float(&self.file, "dimension", 2.0)? != 2.0 {
                    return Err(self.error(line, "only 2-D checkerboards are supported"));
                }
                let color = |name: &str, default: f32| -> Result<[f32; 3], SceneError> {
                    Ok(p.rgb(&self.file, name)?.unwrap_or([default; 3]))
                };
                let (uv_scale, uv_offset) = uv_transform(p)?;
                Ok(TextureDescription::Checkerboard {
                    even: color("tex1", 1.0)?,
                    odd: color("tex2", 0.0)?,
                    uv_scale,
                    uv_offset,
                })
            }
            other => Err(self.error(line, format!("texture \"{other}\" is not supported (imagemap, checkerboard)"))),
        }
    }

    fn material(&mut self, kind: &str, p: &Parameters, line: usize) -> Result<MaterialDescription, SceneError> {
        let file = self.file.clone();
        let file = file.as_path();
        let split = |value: Option<ColorOrTexture>| match value {
            None => (None, None),
            Some(ColorOrTexture::Color(c)) => (Some(c), None),
            Some(ColorOrTexture::Texture(t)) => (None, Some(t)),
        };
        let textures: Vec<String> = self.description.textures.keys().cloned().collect();
        let check_texture = |name: &Option<String>| -> Result<(), SceneError> {
            match name {
                Some(t) if !textures.contains(t) => Err(error_at(file, line, format!("unknown texture \"{t}\""))),
                _ => Ok(()),
            }
        };
        let alpha = |p: &Parameters| -> Result<f32, SceneError> {
            let roughness = p.float(file, "roughness", 0.0)?;
            // Anisotropy is not modelled: the geometric mean of the two roughnesses stands in.
            let u = p.float(file, "uroughness", roughness)?;
            let v = p.float(file, "vroughness", roughness)?;
            let r = (u * v).max(0.0).sqrt();
            Ok(if p.boolean(file, "remaproughness", true)? && r > 0.0 { roughness_to_alpha(r) } else { r })
        };
        let material = match kind {
            "matte" => {
                let (albedo, albedo_texture) = split(p.color_or_texture(file, "Kd")?.or(Some(ColorOrTexture::Color([0.5; 3]))));
                check_texture(&albedo_texture)?;
                if p.float(file, "sigma", 0.0)? != 0.0 {
                    self.warnings.push(format!("line {line}: matte `sigma` (Oren–Nayar) approximated as Lambertian"));
                }
                MaterialDescription::Diffuse { albedo, albedo_texture, opacity_texture: None, emission: None }
            }
            "metal" | "metal_tex" => {
                let eta = p.rgb(file, "eta")?.unwrap_or([0.2004, 0.9240, 1.1022]);
                let k = p.rgb(file, "k")?.unwrap_or([3.9129, 2.4528, 2.1421]);
                let (specular, specular_texture) = split(p.color_or_texture(file, "specularReflectance")?);
                check_texture(&specular_texture)?;
                let alpha = if p.find("roughness").is_none() && p.find("uroughness").is_none() {
                    roughness_to_alpha(0.01)
                } else {
                    alpha(p)?
                };
                MaterialDescription::Conductor {
                    specular,
                    specular_texture,
                    alpha,
                    eta: Some(eta),
                    k: Some(k),
                    opacity_texture: None,
                    emission: None,
                }
            }
            "mirror" => {
                let specular = p.rgb(file, "Kr")?.or(Some([0.9; 3]));
                MaterialDescription::Conductor {
                    specular,
                    specular_texture: None,
                    alpha: 0.0,
                    eta: None,
                    k: None,
                    opacity_texture: None,
                    emission: None,
                }
            }
            "glass" => {
                let rough = p.float(file, "roughness", 0.0)? + p.float(file, "uroughness", 0.0)?;
                if rough > 0.0 {
                    return Err(self.error(line, "rough glass is not supported"));
                }
                let ior = p.float(file, "index", p.float(file, "eta", 1.5)?)?;
                MaterialDescription::Dielectric { ior, emission: None }
            }
            "plastic" | "substrate" => {
                let (albedo, albedo_texture) = split(p.color_or_texture(file, "Kd")?.or(Some(ColorOrTexture::Color([0.25; 3]))));
                check_texture(&albedo_texture)?;
                let ks = p.rgb(file, "Ks")?.unwrap_or([0.25; 3]);
                let alpha = if p.find("roughness").is_none() && p.find("uroughness").is_none() {
                    roughness_to_alpha(0.1)
                } else {
                    alpha(p)?
                };
                self.warnings.push(format!(
                    "line {line}: pbrt's {kind} approximated as a diffuse base under a GGX coat (ior 1.5, coat scaled by Ks)"
                ));
                MaterialDescription::Plastic {
                    albedo,
                    albedo_texture,
                    specular: Some(((ks[0] + ks[1] + ks[2]) / 3.0).clamp(0.0, 1.0)),
                    ior: Some(1.5),
                    alpha,
                    opacity_texture: None,
                    emission: None,
                }
            }
            other => {
                return Err(self.error(
                    line,
                    format!("material \"{other}\" is not supported (matte, metal, metal_tex, mirror, glass, plastic, substrate)"),
                ))
            }
        };
        Ok(material)
    }

    fn light_source(&mut self, kind: &str, p: &Parameters, line: usize) -> Result<(), SceneError> {
        if kind != "infinite" {
            return Err(self.error(line, format!("light \"{kind}\" is not supported (area lights and infinite only)")));
        }
        let scale = p.rgb(&self.file, "scale")?.unwrap_or([1.0; 3]);
        let radiance = p.rgb(&self.file, "L")?.unwrap_or([1.0; 3]);
        let tint = [radiance[0] * scale[0], radiance[1] * scale[1], radiance[2] * scale[2]];
        let environment = match p.string(&self.file, "mapname")? {
            None => EnvironmentDescription::Constant { radiance: tint, sun: None },
            Some(map) => {
                if tint[0] != tint[1] || tint[1] != tint[2] {
                    return Err(self.error(line, "a coloured scale on an environment map is not supported"));
                }
                // pbrt's map looks up light-space l at u = atan2(l.y, l.x)/2π, v = acos(l.z)/π;
                // ours looks up m at u = ½ + atan2(m.x, −m.z)/2π, v = acos(m.y)/π. The two
                // agree for m = (−l.y, l.z, l.x).
                let ours_from_pbrt = Mat3::from_cols(Vec3::Z, Vec3::NEG_X, Vec3::Y);
                let light_to_world = orthonormalize(Mat3::from_mat4(self.attributes.transform))
                    .ok_or_else(|| self.error(line, "the light's transform is not a rotation"))?;
                let rotation = light_to_world * ours_from_pbrt.transpose();
                EnvironmentDescription::Image {
                    file: map.to_string(),
                    scale: Some(tint[0]),
                    rotation: Some(rotation.transpose().to_cols_array_2d()),
                    sun: None,
                }
            }
        };
        if self.description.environment.is_some() {
            return Err(self.error(line, "a second infinite light is not supported"));
        }
        self.description.environment = Some(environment);
        Ok(())
    }

    fn shape(&mut self, kind: &str, p: &Parameters, line: usize) -> Result<(), SceneError> {
        let file = self.file.clone();
        let file = file.as_path();
        let source = match kind {
            "trianglemesh" => {
                let positions =
                    p.numbers(file, "P")?.ok_or_else(|| self.error(line, "trianglemesh without \"point P\""))?;
                if positions.len() % 3 != 0 {
                    return Err(self.error(line, "\"point P\" is not a list of 3-D points"));
                }
                let positions: Vec<Vec3> = positions.chunks_exact(3).map(vec3).collect();
                let indices = match p.numbers(file, "indices")? {
                    Some(i) => i.iter().map(|&v| v as u32).collect(),
                    None if positions.len() == 3 => vec![0, 1, 2],
                    None => return Err(self.error(line, "trianglemesh without \"integer indices\"")),
                };
                let normals = p.numbers(file, "N")?.map(|n| n.chunks_exact(3).map(vec3).collect::<Vec<_>>());
                let uvs = p
                    .numbers(file, "uv")?
                    .or(p.numbers(file, "st")?)
                    .map(|t| t.chunks_exact(2).map(|t| [t[0], t[1]]).collect::<Vec<_>>());
                ShapeSource::Inline { positions, indices, normals, uvs }
            }
            "plymesh" => {
                let name = p
                    .string(file, "filename")?
                    .ok_or_else(|| self.error(line, "plymesh without \"string filename\""))?;
                let has_normals = ply_has_normals(&self.folder.join(name));
                ShapeSource::Ply { file: name.to_string(), has_normals }
            }
            other => {
                return Err(self.error(line, format!("shape \"{other}\" is not supported (trianglemesh, plymesh)")))
            }
        };
        if p.find("alpha").is_some() {
            return Err(self.error(line, "alpha-masked shapes are not supported"));
        }
        let material = match &self.attributes.material {
            Some(m) => m.clone(),
            None => {
                // pbrt's default material: matte 0.5.
                let name = "default-matte".to_string();
                self.description.materials.entry(name.clone()).or_insert(MaterialDescription::Diffuse {
                    albedo: Some([0.5; 3]),
                    albedo_texture: None,
                    opacity_texture: None,
                    emission: None,
                });
                name
            }
        };
        let material = match self.attributes.area_light {
            None => material,
            Some(radiance) => self.emissive(&material, radiance, line)?,
        };
        // Without normals pbrt's front is the winding's, reversed by ReverseOrientation
        // and by a transform that swaps handedness.
        let flip = self.attributes.reverse_orientation ^ (self.attributes.transform.determinant() < 0.0);
        let shape = ObjectShape { shape: source, material, transform: self.attributes.transform, flip };
        match &mut self.current_object {
            Some((_, shapes)) => shapes.push(shape),
            None => self.emit(shape),
        }
        Ok(())
    }

    /// A variant of `material` that emits `radiance` from its front.
    fn emissive(&mut self, material: &str, radiance: [f32; 3], line: usize) -> Result<String, SceneError> {
        let key = (material.to_string(), radiance.map(f32::to_bits));
        if let Some(name) = self.emissive_variants.get(&key) {
            return Ok(name.clone());
        }
        let emitting = self.description.materials[material].emitting(radiance);
        let name = format!("{material} (emitting, line {line})");
        self.description.materials.insert(name.clone(), emitting);
        self.emissive_variants.insert(key, name.clone());
        Ok(name)
    }

    fn emit(&mut self, shape: ObjectShape) {
        let ObjectShape { shape, material, transform, flip } = shape;
        let description = match shape {
            ShapeSource::Ply { file, has_normals } => ShapeDescription::Mesh {
                file,
                material: Some(material),
                transform: (transform != Mat4::IDENTITY).then_some(rows_of(transform)),
                face_normals: false,
                // With normals, pbrt's front faces them whatever the orientation flags.
                flip: flip && !has_normals,
                front_from_normals: has_normals,
            },
            ShapeSource::Inline { positions, mut indices, normals, uvs } => {
                let normal_matrix = Mat3::from_mat4(transform).inverse().transpose();
                if flip && normals.is_none() {
                    for t in indices.chunks_exact_mut(3) {
                        t.swap(1, 2);
                    }
                }
                ShapeDescription::Triangles {
                    positions: positions.iter().map(|&p| transform.transform_point3(p).to_array()).collect(),
                    front_from_normals: normals.is_some(),
                    normals: normals.map(|n| n.iter().map(|&n| (normal_matrix * n).to_array()).collect()),
                    uvs,
                    indices,
                    material,
                }
            }
        };
        self.description.shapes.push(description);
    }

    fn finish(mut self) -> Result<Imported, SceneError> {
        if let Some((_, open)) = self.stack.last() {
            let what = if *open { "TransformBegin" } else { "AttributeBegin" };
            return Err(self.error(self.stack.len(), format!("{what} never closed")));
        }
        let (camera_to_world, camera) =
            self.camera_to_world.clone().ok_or_else(|| SceneError::new(&self.file, "", "no Camera directive"))?;
        let film = self.film.clone().unwrap_or_default();
        let width = film.float(&self.file, "xresolution", 1280.0)? as u32;
        let height = film.float(&self.file, "yresolution", 720.0)? as u32;
        let fov = camera.float(&self.file, "fov", 90.0)?;
        // pbrt's fov spans the shorter image axis.
        self.description.camera = camera_from_matrix(camera_to_world, Vec3::X, (fov, width < height), width, height)
            .ok_or_else(|| SceneError::new(&self.file, "", "the camera transform collapses the view"))?;
        if self.description.shapes.is_empty() {
            return Err(SceneError::new(&self.file, "", "no shapes"));
        }
        for (directive, count) in &self.skipped {
            self.warnings.push(format!("{directive} ignored ({count}×): the tracer's own settings apply"));
        }
        Ok(Imported { description: self.description, warnings: self.warnings })
    }
}

/// The nearest rotation to `m` (which must be one up to scale), or `None`.
fn orthonormalize(m: Mat3) -> Option<Mat3> {
    let x = m.x_axis.try_normalize()?;
    let y = (m.y_axis - x * x.dot(m.y_axis)).try_normalize()?;
    let z = x.cross(y);
    (z.dot(m.z_axis) > 0.0).then_some(Mat3::from_cols(x, y, z))
}
