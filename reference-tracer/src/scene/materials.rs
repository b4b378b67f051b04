//! A scene's textures and materials, checked and built from their descriptions.

use std::collections::HashMap;
use std::path::Path;

use glam::{Vec2, Vec3};

use super::{MaterialDescription, MtlMaterial, TextureDescription, TextureEncoding};
use crate::color::is_valid_radiance;
use crate::material::{ComplexIor, Material, Plastic, Surface};
use crate::texture::Texture;

pub(super) fn reflectance(values: [f32; 3], field: &'static str) -> Result<Vec3, (&'static str, String)> {
    let v = Vec3::from(values);
    if v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0 {
        Ok(v)
    } else {
        Err((field, format!("{values:?} must lie in [0, 1]")))
    }
}

pub(super) fn build_texture(texture: &TextureDescription, folder: &Path) -> Result<Texture, (&'static str, String)> {
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

pub(super) fn positive_finite(value: f32, field: &'static str) -> Result<f32, (&'static str, String)> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err((field, format!("{value} must be finite and positive")))
    }
}

pub(super) fn build_material(
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

impl MtlMaterial {
    /// What the tracer takes of it: the diffuse reflectance `Kd` clamped to [0, 1] and the
    /// emitted radiance `Ke`, at least 0 (a vector with a non-finite part is black).
    pub fn albedo_and_emission(&self) -> (Vec3, Vec3) {
        let finite = |v: [f32; 3]| {
            let v = Vec3::from(v);
            if v.is_finite() {
                v.max(Vec3::ZERO)
            } else {
                Vec3::ZERO
            }
        };
        (finite(self.diffuse).min(Vec3::ONE), finite(self.emission))
    }
}

/// A scene material for an MTL material: diffuse, emitting
/// ([`MtlMaterial::albedo_and_emission`]).
pub(super) fn mtl_material(mtl: &MtlMaterial) -> Material {
    let (albedo, emission) = mtl.albedo_and_emission();
    Material::new(Surface::Diffuse { albedo }, emission)
}
