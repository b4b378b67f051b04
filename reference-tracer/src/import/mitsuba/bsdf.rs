//! Mitsuba's bsdfs (and the indices of refraction it knows by name) as the project's
//! materials.

use std::collections::HashMap;

use roxmltree::Node;

use super::{Reader, Value};
use crate::import::error_at;
use crate::scene::{MaterialDescription, SceneError};

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

impl<'input> Reader<'_, 'input> {
    pub(super) fn ior(
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
    pub(super) fn bsdf(&mut self, node: Node) -> Result<(MaterialDescription, bool), SceneError> {
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
}
