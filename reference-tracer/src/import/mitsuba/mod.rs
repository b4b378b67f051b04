//! A Mitsuba 0.5 XML reader (roxmltree) for the subset real scenes use: a perspective
//! sensor (`lookat` or `matrix` transforms, `fov` along `fovAxis`), an hdrfilm's size,
//! shapes obj / ply / rectangle / disk / cube / sphere with `toWorld`, area and envmap
//! emitters, bsdfs diffuse / roughplastic / plastic / roughconductor / conductor /
//! dielectric / thindielectric / twosided / mask, bitmap textures, and `ref`s to bsdfs
//! and textures declared at the top level.
//!
//! Every reflective surface reflects on both sides (the tracer's materials are
//! two-sided): a bare one-sided bsdf is read as if wrapped in `twosided`, with a warning.

mod bsdf;
mod translate;

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::{Mat4, Vec3};
use roxmltree::{Document, Node};

use super::{camera_from_matrix, error_at, Imported};
use crate::scene::{
    CameraDescription, EnvironmentDescription, MaterialDescription, SceneError, ShapeDescription, TextureDescription,
    TextureEncoding,
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
}
