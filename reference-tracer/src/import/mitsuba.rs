//! A Mitsuba 0.5 XML reader (roxmltree) for the subset real scenes use: a perspective
//! sensor (`lookat` or `matrix` transforms, `fov` along `fovAxis`), an hdrfilm's size,
//! shapes obj / ply / rectangle / disk / cube / sphere with `toWorld`, area and envmap
//! emitters, bsdfs diffuse / roughplastic / plastic / roughconductor / conductor /
//! dielectric / thindielectric / twosided / mask, bitmap textures, and `ref`s to bsdfs
//! and textures declared at the top level.
//!
//! Every reflective surface reflects on both sides (the tracer's materials are
//! two-sided): a bare one-sided bsdf is read as if wrapped in `twosided`, with a warning.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::{Mat3, Mat4, Vec3};
use roxmltree::{Document, Node};

use super::primitives::{primitive_shape, Primitive};
use super::{camera_from_matrix, error_at, rows_of, Imported};
use crate::scene::{
    CameraDescription, EnvironmentDescription, MaterialDescription, SceneDescription, SceneError, ShapeDescription,
    TextureDescription, TextureEncoding,
};

/// Reads the Mitsuba scene `text` of `file`.
pub fn read(file: &Path, text: &str) -> Result<Imported, SceneError> {
    let document =
        Document::parse(text).map_err(|e| error_at(file, e.pos().row as usize, format!("malformed XML: {e}")))?;
    let mut reader = Reader {
        file,
        document: &document,
        textures: BTreeMap::new(),
        texture_names: HashMap::new(),
        materials: BTreeMap::new(),
        shapes: Vec::new(),
        environment: None,
        camera: None,
        warnings: Vec::new(),
        bsdf_ids: HashMap::new(),
        texture_ids: HashMap::new(),
        one_sided: 0,
    };
    let scene = document.root_element();
    if scene.tag_name().name() != "scene" {
        return Err(reader.error(scene, "the root element must be <scene>"));
    }
    for node in scene.children().filter(Node::is_element) {
        reader.top_level(node)?;
    }
    reader.finish()
}

/// A value an element's child gives a named parameter.
#[derive(Clone, Debug)]
enum Value {
    Number(f32),
    Color([f32; 3]),
    Text(String),
    Boolean(bool),
    Texture(String),
}

struct Reader<'a, 'input> {
    file: &'a Path,
    document: &'a Document<'input>,
    textures: BTreeMap<String, TextureDescription>,
    /// Texture names by what they read, so one file read twice is one texture.
    texture_names: HashMap<String, String>,
    materials: BTreeMap<String, MaterialDescription>,
    shapes: Vec<ShapeDescription>,
    environment: Option<EnvironmentDescription>,
    camera: Option<CameraDescription>,
    warnings: Vec<String>,
    /// Top-level bsdfs by id: the material's name.
    bsdf_ids: HashMap<String, String>,
    /// Top-level textures by id: the texture's name.
    texture_ids: HashMap<String, String>,
    /// Shapes whose bsdf was one-sided.
    one_sided: usize,
}

/// Indices of refraction Mitsuba knows by name (its documentation's table).
const NAMED_IORS: [(&str, f32); 16] = [
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.333),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
];

/// More of Mitsuba's named indices (solids).
const NAMED_SOLID_IORS: [(&str, f32); 7] = [
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.575),
    ("diamond", 2.419),
];

fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn numbers(text: &str) -> Option<Vec<f32>> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect()
}

impl<'input> Reader<'_, 'input> {
    fn line(&self, node: Node) -> usize {
        self.document.text_pos_at(node.range().start).row as usize
    }

    fn error(&self, node: Node, message: impl Into<String>) -> SceneError {
        error_at(self.file, self.line(node), message)
    }

    fn attribute<'n>(&self, node: Node<'n, 'input>, name: &str) -> Result<&'n str, SceneError> {
        let value = node
            .attribute(name)
            .ok_or_else(|| self.error(node, format!("<{}> needs a `{name}` attribute", node.tag_name().name())))?;
        if value.contains('$') {
            return Err(self.error(node, format!("`{name}=\"{value}\"`: $parameters are not supported")));
        }
        Ok(value)
    }

    fn number_attribute(&self, node: Node, name: &str) -> Result<f32, SceneError> {
        let text = self.attribute(node, name)?;
        match numbers(text).as_deref() {
            Some([v]) => Ok(*v),
            _ => Err(self.error(node, format!("`{name}=\"{text}\"` is not one finite number"))),
        }
    }

    fn vector_attribute(&self, node: Node, name: &str) -> Result<Vec3, SceneError> {
        let text = self.attribute(node, name)?;
        match numbers(text).as_deref() {
            Some([x, y, z]) => Ok(Vec3::new(*x, *y, *z)),
            _ => Err(self.error(node, format!("`{name}=\"{text}\"` is not three finite numbers"))),
        }
    }

    /// The named parameters among `node`'s children (float, integer, boolean, string,
    /// rgb, srgb, spectrum, texture and named refs), by name.
    fn parameters(&mut self, node: Node) -> Result<HashMap<String, (Value, usize)>, SceneError> {
        let mut parameters = HashMap::new();
        for child in node.children().filter(Node::is_element) {
            let tag = child.tag_name().name();
            let Some(name) = child.attribute("name") else { continue };
            if matches!(
                tag,
                "transform" | "bsdf" | "emitter" | "sampler" | "film" | "rfilter" | "medium" | "point" | "vector"
            ) {
                continue;
            }
            let value = match tag {
                "float" | "integer" => Value::Number(self.number_attribute(child, "value")?),
                "boolean" => match self.attribute(child, "value")? {
                    "true" => Value::Boolean(true),
                    "false" => Value::Boolean(false),
                    other => return Err(self.error(child, format!("boolean `{name}` is \"{other}\""))),
                },
                "string" => Value::Text(self.attribute(child, "value")?.to_string()),
                "rgb" | "srgb" | "spectrum" => {
                    let text = self.attribute(child, "value")?;
                    if tag == "spectrum" && text.contains(':') {
                        return Err(self.error(child, format!("spectrum `{name}`: sampled spectra are not supported")));
                    }
                    let values = numbers(text)
                        .ok_or_else(|| self.error(child, format!("`{name}`: \"{text}\" is not numbers")))?;
                    let rgb = match values.as_slice() {
                        [v] => [*v; 3],
                        [r, g, b] => [*r, *g, *b],
                        _ => return Err(self.error(child, format!("`{name}`: expected 1 or 3 numbers"))),
                    };
                    Value::Color(if tag == "srgb" { rgb.map(srgb_to_linear) } else { rgb })
                }
                "texture" => Value::Texture(self.texture(child)?),
                "ref" => {
                    let id = self.attribute(child, "id")?;
                    match self.texture_ids.get(id) {
                        Some(texture) => Value::Texture(texture.clone()),
                        None => {
                            return Err(self.error(child, format!("`{name}` refers to \"{id}\", which is no texture")))
                        }
                    }
                }
                other => return Err(self.error(child, format!("unknown parameter element <{other}>"))),
            };
            parameters.insert(name.to_string(), (value, self.line(child)));
        }
        Ok(parameters)
    }

    fn texture(&mut self, node: Node) -> Result<String, SceneError> {
        let kind = self.attribute(node, "type")?;
        if kind != "bitmap" {
            return Err(self.error(node, format!("texture \"{kind}\" is not supported (bitmap only)")));
        }
        let parameters = self.parameters(node)?;
        let text = |name: &str| match parameters.get(name) {
            Some((Value::Text(t), _)) => Some(t.clone()),
            _ => None,
        };
        let number = |name: &str, default: f32| match parameters.get(name) {
            Some((Value::Number(v), _)) => *v,
            _ => default,
        };
        let file = text("filename").ok_or_else(|| self.error(node, "bitmap without a `filename`"))?;
        let scale = [number("uscale", 1.0), number("vscale", 1.0)];
        let offset = [number("uoffset", 0.0), number("voffset", 0.0)];
        // gamma: −1 (the default) decodes 8-bit files by sRGB; 1 keeps them linear.
        let encoding = (number("gamma", -1.0) == 1.0).then_some(TextureEncoding::Linear);
        let description = TextureDescription::Image {
            file: file.clone(),
            encoding,
            uv_scale: (scale != [1.0; 2]).then_some(scale),
            uv_offset: (offset != [0.0; 2]).then_some(offset),
        };
        let key = format!("{description:?}");
        if let Some(name) = self.texture_names.get(&key) {
            return Ok(name.clone());
        }
        let stem = Path::new(&file).file_stem().and_then(|s| s.to_str()).unwrap_or("texture");
        let mut name = stem.to_string();
        let mut n = 2;
        while self.textures.contains_key(&name) {
            name = format!("{stem}-{n}");
            n += 1;
        }
        self.textures.insert(name.clone(), description);
        self.texture_names.insert(key, name.clone());
        Ok(name)
    }

    /// The transform of a `<transform>` element: each child applied after the previous.
    fn transform(&self, node: Node) -> Result<Mat4, SceneError> {
        let mut matrix = Mat4::IDENTITY;
        for child in node.children().filter(Node::is_element) {
            let step = match child.tag_name().name() {
                "matrix" => {
                    let text = self.attribute(child, "value")?;
                    let values = numbers(text).filter(|v| v.len() == 16);
                    let values = values.ok_or_else(|| self.error(child, "a matrix takes 16 finite numbers"))?;
                    // Mitsuba writes matrices row by row.
                    Mat4::from_cols_slice(&values).transpose()
                }
                "translate" => Mat4::from_translation(self.xyz(child, 0.0)?),
                "scale" => match child.attribute("value") {
                    Some(_) => Mat4::from_scale(Vec3::splat(self.number_attribute(child, "value")?)),
                    None => Mat4::from_scale(self.xyz(child, 1.0)?),
                },
                "rotate" => {
                    let axis = self
                        .xyz(child, 0.0)?
                        .try_normalize()
                        .ok_or_else(|| self.error(child, "rotation about a zero axis"))?;
                    Mat4::from_axis_angle(axis, self.number_attribute(child, "angle")?.to_radians())
                }
                "lookat" | "lookAt" => {
                    let origin = self.vector_attribute(child, "origin")?;
                    let target = self.vector_attribute(child, "target")?;
                    let up = match child.attribute("up") {
                        Some(_) => self.vector_attribute(child, "up")?,
                        None => Vec3::Y,
                    };
                    let dir = (target - origin)
                        .try_normalize()
                        .ok_or_else(|| self.error(child, "lookat: origin = target"))?;
                    let left = up
                        .cross(dir)
                        .try_normalize()
                        .ok_or_else(|| self.error(child, "lookat: up is parallel to the view"))?;
                    let new_up = dir.cross(left);
                    Mat4::from_cols(left.extend(0.0), new_up.extend(0.0), dir.extend(0.0), origin.extend(1.0))
                }
                other => return Err(self.error(child, format!("unknown transform step <{other}>"))),
            };
            matrix = step * matrix;
        }
        if !matrix.is_finite() {
            return Err(self.error(node, "the transform is not finite"));
        }
        Ok(matrix)
    }

    fn xyz(&self, node: Node, default: f32) -> Result<Vec3, SceneError> {
        let mut v = Vec3::splat(default);
        if node.attribute("value").is_some() {
            return self.vector_attribute(node, "value");
        }
        for (i, axis) in ["x", "y", "z"].into_iter().enumerate() {
            if node.attribute(axis).is_some() {
                v[i] = self.number_attribute(node, axis)?;
            }
        }
        Ok(v)
    }

    fn named_transform(&self, node: Node, name: &str) -> Result<Mat4, SceneError> {
        match node.children().find(|c| c.has_tag_name("transform") && c.attribute("name") == Some(name)) {
            Some(t) => self.transform(t),
            None => Ok(Mat4::IDENTITY),
        }
    }

    fn top_level(&mut self, node: Node) -> Result<(), SceneError> {
        match node.tag_name().name() {
            "integrator" | "sampler" => self.warnings.push(format!(
                "line {}: <{}> ignored: the tracer's own settings apply",
                self.line(node),
                node.tag_name().name()
            )),
            "sensor" => self.sensor(node)?,
            "bsdf" => {
                let id = self.attribute(node, "id")?.to_string();
                let (material, one_sided) = self.bsdf(node)?;
                if one_sided {
                    self.warnings
                        .push(format!("line {}: bsdf \"{id}\" is one-sided; read as two-sided", self.line(node)));
                }
                self.materials.insert(id.clone(), material);
                self.bsdf_ids.insert(id.clone(), id);
            }
            "texture" => {
                let id = self.attribute(node, "id")?.to_string();
                let name = self.texture(node)?;
                self.texture_ids.insert(id, name);
            }
            "shape" => self.shape(node)?,
            "emitter" => self.emitter(node)?,
            other => return Err(self.error(node, format!("<{other}> is not supported here"))),
        }
        Ok(())
    }

    fn sensor(&mut self, node: Node) -> Result<(), SceneError> {
        let kind = self.attribute(node, "type")?;
        if kind != "perspective" && kind != "thinlens" {
            return Err(self.error(node, format!("sensor \"{kind}\" is not supported (perspective)")));
        }
        if kind == "thinlens" {
            self.warnings
                .push(format!("line {}: thinlens sensor read as a pinhole (no depth of field)", self.line(node)));
        }
        let parameters = self.parameters(node)?;
        let fov = match parameters.get("fov") {
            Some((Value::Number(v), _)) => *v,
            _ => return Err(self.error(node, "the sensor needs a `fov`")),
        };
        let (mut width, mut height) = (768u32, 576u32);
        if let Some(film) = node.children().find(|c| c.has_tag_name("film")) {
            let film_parameters = self.parameters(film)?;
            for (name, side) in [("width", &mut width), ("height", &mut height)] {
                if let Some((Value::Number(v), line)) = film_parameters.get(name) {
                    if !(*v >= 1.0 && *v <= crate::scene::MAX_IMAGE_SIDE as f32) {
                        return Err(error_at(self.file, *line, format!("film {name} {v} out of range")));
                    }
                    *side = *v as u32;
                }
            }
        }
        let axis = match parameters.get("fovAxis") {
            Some((Value::Text(t), _)) => t.as_str(),
            _ => "x",
        };
        let horizontal = match axis {
            "x" => true,
            "y" => false,
            "smaller" => width <= height,
            "larger" => width >= height,
            other => {
                return Err(self.error(node, format!("fovAxis \"{other}\" is not supported (x, y, smaller, larger)")))
            }
        };
        let to_world = self.named_transform(node, "toWorld")?;
        // Mitsuba's camera looks along +z with +x to the image's left.
        let camera = camera_from_matrix(to_world, Vec3::NEG_X, (fov, horizontal), width, height)
            .ok_or_else(|| self.error(node, "the sensor transform collapses the view"))?;
        self.camera = Some(camera);
        Ok(())
    }

    fn ior(
        &self,
        node: Node,
        parameters: &HashMap<String, (Value, usize)>,
        name: &str,
        default: f32,
    ) -> Result<f32, SceneError> {
        match parameters.get(name) {
            None => Ok(default),
            Some((Value::Number(v), _)) => Ok(*v),
            Some((Value::Text(t), line)) => NAMED_IORS
                .iter()
                .chain(&NAMED_SOLID_IORS)
                .find(|(n, _)| n.eq_ignore_ascii_case(t))
                .map(|(_, v)| *v)
                .ok_or_else(|| error_at(self.file, *line, format!("unknown index of refraction \"{t}\""))),
            Some(_) => Err(self.error(node, format!("`{name}` must be a number or a material name"))),
        }
    }

    /// A bsdf element as a material, and whether it was one-sided (not `twosided`).
    fn bsdf(&mut self, node: Node) -> Result<(MaterialDescription, bool), SceneError> {
        let kind = self.attribute(node, "type")?;
        let inner = |reader: &mut Self| -> Result<(MaterialDescription, bool), SceneError> {
            let child = node
                .children()
                .find(|c| c.has_tag_name("bsdf") || (c.has_tag_name("ref") && c.attribute("name").is_none()))
                .ok_or_else(|| reader.error(node, format!("{kind} needs a nested bsdf")))?;
            if child.has_tag_name("ref") {
                let id = reader.attribute(child, "id")?;
                let name =
                    reader.bsdf_ids.get(id).ok_or_else(|| reader.error(child, format!("unknown bsdf \"{id}\"")))?;
                return Ok((reader.materials[name].clone(), false));
            }
            reader.bsdf(child)
        };
        let parameters = self.parameters(node)?;
        let color = |name: &str, default: Option<[f32; 3]>| -> Result<(Option<[f32; 3]>, Option<String>), SceneError> {
            match parameters.get(name) {
                None => Ok((default, None)),
                Some((Value::Color(c), _)) => Ok((Some(*c), None)),
                Some((Value::Number(v), _)) => Ok((Some([*v; 3]), None)),
                Some((Value::Texture(t), _)) => Ok((None, Some(t.clone()))),
                Some((_, line)) => Err(error_at(self.file, *line, format!("`{name}` must be a colour or a texture"))),
            }
        };
        let number = |name: &str, default: f32| -> Result<f32, SceneError> {
            match parameters.get(name) {
                None => Ok(default),
                Some((Value::Number(v), _)) => Ok(*v),
                Some((_, line)) => Err(error_at(self.file, *line, format!("`{name}` must be a number"))),
            }
        };
        let distribution = |reader: &mut Self| {
            if let Some((Value::Text(d), line)) = parameters.get("distribution") {
                if d != "ggx" {
                    reader.warnings.push(format!("line {line}: microfacet distribution \"{d}\" approximated by GGX"));
                }
            }
        };
        let material = match kind {
            "twosided" => return Ok((inner(self)?.0, false)),
            "mask" => {
                let (mut material, one_sided) = inner(self)?;
                let opacity = match parameters.get("opacity") {
                    Some((Value::Texture(t), _)) => t.clone(),
                    Some((Value::Number(v) | Value::Color([v, _, _]), _)) if *v >= 1.0 => {
                        return Ok((material, one_sided))
                    }
                    _ => return Err(self.error(node, "mask needs an opacity texture")),
                };
                match &mut material {
                    MaterialDescription::Diffuse { opacity_texture, .. }
                    | MaterialDescription::Conductor { opacity_texture, .. }
                    | MaterialDescription::Plastic { opacity_texture, .. } => *opacity_texture = Some(opacity),
                    _ => return Err(self.error(node, "a mask over glass is not supported")),
                }
                return Ok((material, one_sided));
            }
            "diffuse" => {
                let (albedo, albedo_texture) = color("reflectance", Some([0.5; 3]))?;
                MaterialDescription::Diffuse { albedo, albedo_texture, opacity_texture: None, emission: None }
            }
            "roughplastic" | "plastic" => {
                distribution(self);
                let (albedo, albedo_texture) = color("diffuseReflectance", Some([0.5; 3]))?;
                let (specular, specular_texture) = color("specularReflectance", Some([1.0; 3]))?;
                if specular_texture.is_some() {
                    return Err(self.error(node, "a textured specularReflectance on plastic is not supported"));
                }
                let specular = specular.map(|s| (s[0] + s[1] + s[2]) / 3.0);
                let ior =
                    self.ior(node, &parameters, "intIOR", 1.49)? / self.ior(node, &parameters, "extIOR", 1.000277)?;
                if matches!(parameters.get("nonlinear"), Some((Value::Boolean(false), _)) | None) {
                    self.warnings.push(format!(
                        "line {}: plastic with nonlinear=false read with the nonlinear inter-reflection term",
                        self.line(node)
                    ));
                }
                let alpha = if kind == "plastic" { 0.0 } else { number("alpha", 0.1)? };
                MaterialDescription::Plastic {
                    albedo,
                    albedo_texture,
                    specular,
                    ior: Some(ior),
                    alpha,
                    opacity_texture: None,
                    emission: None,
                }
            }
            "roughconductor" | "conductor" => {
                distribution(self);
                let (specular, specular_texture) = color("specularReflectance", Some([1.0; 3]))?;
                let named = match parameters.get("material") {
                    Some((Value::Text(t), _)) => Some(t.as_str()),
                    _ => None,
                };
                let (eta, k) = match (named, color("eta", None)?.0, color("k", None)?.0) {
                    (Some("none"), _, _) => (None, None),
                    (_, Some(eta), Some(k)) => {
                        let ext = self.ior(node, &parameters, "extEta", 1.000277)?;
                        (Some(eta.map(|e| e / ext)), Some(k.map(|k| k / ext)))
                    }
                    (Some(other), _, _) => {
                        return Err(self
                            .error(node, format!("named conductor \"{other}\" is not supported: give `eta` and `k`")))
                    }
                    (None, _, _) => {
                        return Err(self.error(node, "a conductor needs `eta` and `k` (or material \"none\")"))
                    }
                };
                let alpha = if kind == "conductor" { 0.0 } else { number("alpha", 0.1)? };
                MaterialDescription::Conductor {
                    specular,
                    specular_texture,
                    alpha,
                    eta,
                    k,
                    opacity_texture: None,
                    emission: None,
                }
            }
            "dielectric" | "thindielectric" => {
                let ior =
                    self.ior(node, &parameters, "intIOR", 1.5046)? / self.ior(node, &parameters, "extIOR", 1.000277)?;
                if kind == "dielectric" {
                    MaterialDescription::Dielectric { ior, emission: None }
                } else {
                    MaterialDescription::ThinDielectric { ior, emission: None }
                }
            }
            other => return Err(self.error(node, format!("bsdf \"{other}\" is not supported"))),
        };
        let one_sided =
            !matches!(material, MaterialDescription::Dielectric { .. } | MaterialDescription::ThinDielectric { .. });
        Ok((material, one_sided))
    }

    fn shape(&mut self, node: Node) -> Result<(), SceneError> {
        let kind = self.attribute(node, "type")?;
        let parameters = self.parameters(node)?;
        let to_world = self.named_transform(node, "toWorld")?;
        let flag = |name: &str| matches!(parameters.get(name), Some((Value::Boolean(true), _)));
        let flip = flag("flipNormals");
        // The material: a nested bsdf, a ref to one, or Mitsuba's default (diffuse 0.5).
        let mut material = None;
        for child in node.children().filter(Node::is_element) {
            match child.tag_name().name() {
                "bsdf" => {
                    let (m, one_sided) = self.bsdf(child)?;
                    self.one_sided += one_sided as usize;
                    let name = format!("shape-line-{}", self.line(child));
                    self.materials.insert(name.clone(), m);
                    material = Some(name);
                }
                "ref" if child.attribute("name").is_none() => {
                    let id = self.attribute(child, "id")?;
                    let name =
                        self.bsdf_ids.get(id).ok_or_else(|| self.error(child, format!("unknown bsdf \"{id}\"")))?;
                    material = Some(name.clone());
                }
                "medium" => return Err(self.error(child, "participating media are not supported")),
                _ => {}
            }
        }
        let mut material = material.unwrap_or_else(|| {
            let name = "default-diffuse".to_string();
            self.materials.entry(name.clone()).or_insert(MaterialDescription::Diffuse {
                albedo: Some([0.5; 3]),
                albedo_texture: None,
                opacity_texture: None,
                emission: None,
            });
            name
        });
        if let Some(emitter) = node.children().find(|c| c.has_tag_name("emitter")) {
            let emitter_kind = self.attribute(emitter, "type")?;
            if emitter_kind != "area" {
                return Err(self.error(emitter, format!("emitter \"{emitter_kind}\" on a shape (area only)")));
            }
            let radiance = match self.parameters(emitter)?.get("radiance") {
                Some((Value::Color(c), _)) => *c,
                Some((Value::Number(v), _)) => [*v; 3],
                _ => return Err(self.error(emitter, "an area emitter needs a `radiance`")),
            };
            material = self.emissive(&material, radiance, self.line(emitter));
        }
        let shape = match kind {
            "obj" | "ply" => {
                let file = match parameters.get("filename") {
                    Some((Value::Text(f), _)) => f.clone(),
                    _ => return Err(self.error(node, format!("{kind} shape without a `filename`"))),
                };
                let face_normals = flag("faceNormals");
                ShapeDescription::Mesh {
                    file,
                    material: Some(material),
                    transform: (to_world != Mat4::IDENTITY).then_some(rows_of(to_world)),
                    face_normals,
                    flip,
                    // Mitsuba's front is the side of the shading normal.
                    front_from_normals: !face_normals,
                }
            }
            "rectangle" => primitive_shape(Primitive::Rectangle, to_world, flip, &material),
            "disk" => primitive_shape(Primitive::Disk, to_world, flip, &material),
            "cube" => primitive_shape(Primitive::Cube, to_world, flip, &material),
            "sphere" => {
                let radius = match parameters.get("radius") {
                    Some((Value::Number(r), _)) => *r,
                    _ => 1.0,
                };
                let center = match node.children().find(|c| c.attribute("name") == Some("center")) {
                    Some(point) => self.xyz(point, 0.0)?,
                    None => Vec3::ZERO,
                };
                let local = Mat4::from_translation(center) * Mat4::from_scale(Vec3::splat(radius));
                primitive_shape(Primitive::Sphere, to_world * local, flip, &material)
            }
            other => {
                return Err(self.error(
                    node,
                    format!("shape \"{other}\" is not supported (obj, ply, rectangle, disk, cube, sphere)"),
                ))
            }
        };
        self.shapes.push(shape);
        Ok(())
    }

    /// A variant of `material` that emits `radiance` from its front.
    fn emissive(&mut self, material: &str, radiance: [f32; 3], line: usize) -> String {
        let emitting = self.materials[material].emitting(radiance);
        let name = format!("emitter-line-{line}");
        self.materials.insert(name.clone(), emitting);
        name
    }

    fn emitter(&mut self, node: Node) -> Result<(), SceneError> {
        let kind = self.attribute(node, "type")?;
        let parameters = self.parameters(node)?;
        let environment = match kind {
            "envmap" => {
                let file = match parameters.get("filename") {
                    Some((Value::Text(f), _)) => f.clone(),
                    _ => return Err(self.error(node, "envmap without a `filename`")),
                };
                let scale = match parameters.get("scale") {
                    Some((Value::Number(s), _)) => Some(*s),
                    _ => None,
                };
                let to_world = self.named_transform(node, "toWorld")?;
                let rotation = Mat3::from_mat4(to_world);
                if !(rotation * rotation.transpose()).abs_diff_eq(Mat3::IDENTITY, 1e-3) {
                    return Err(self.error(node, "the envmap's toWorld must be a rotation"));
                }
                // Mitsuba looks up local direction v at u = atan2(v.x, −v.z)/2π; ours puts
                // u = ½ there: the same map turned half a revolution about +y.
                let rotation = rotation * Mat3::from_rotation_y(std::f32::consts::PI);
                EnvironmentDescription::Image {
                    file,
                    scale,
                    rotation: Some(rotation.transpose().to_cols_array_2d()),
                    sun: None,
                }
            }
            "constant" => match parameters.get("radiance") {
                Some((Value::Color(c), _)) => EnvironmentDescription::Constant { radiance: *c, sun: None },
                Some((Value::Number(v), _)) => EnvironmentDescription::Constant { radiance: [*v; 3], sun: None },
                _ => return Err(self.error(node, "a constant emitter needs a `radiance`")),
            },
            other => {
                return Err(self.error(node, format!("emitter \"{other}\" is not supported (envmap, constant, area)")))
            }
        };
        if self.environment.is_some() {
            return Err(self.error(node, "a second environment emitter is not supported"));
        }
        self.environment = Some(environment);
        Ok(())
    }

    fn finish(mut self) -> Result<Imported, SceneError> {
        let camera = self.camera.take().ok_or_else(|| SceneError::new(self.file, "", "no <sensor>"))?;
        if self.shapes.is_empty() {
            return Err(SceneError::new(self.file, "", "no shapes"));
        }
        if self.one_sided > 0 {
            self.warnings.push(format!("{} shapes have one-sided bsdfs; read as two-sided", self.one_sided));
        }
        let description = SceneDescription {
            format: 1,
            camera,
            textures: self.textures,
            materials: self.materials,
            shapes: self.shapes,
            environment: self.environment,
        };
        Ok(Imported { description, warnings: self.warnings })
    }
}
