//! Translation of pbrt's textures, materials, lights and shapes into the project's
//! scene description.

use glam::{Mat3, Mat4, Vec3};

use super::parameters::{ColorOrTexture, Parameters};
use super::{roughness_to_alpha, vec3, ObjectShape, Reader, ShapeSource, UvTransform};
use crate::import::{camera_from_matrix, error_at, rows_of, Imported};
use crate::scene::{
    ply_has_normals, EnvironmentDescription, MaterialDescription, SceneError, ShapeDescription, TextureDescription,
    TextureEncoding,
};

impl Reader {
    pub(super) fn texture(&self, class: &str, p: &Parameters, line: usize) -> Result<TextureDescription, SceneError> {
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

    pub(super) fn material(
        &mut self,
        kind: &str,
        p: &Parameters,
        line: usize,
    ) -> Result<MaterialDescription, SceneError> {
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

    pub(super) fn light_source(&mut self, kind: &str, p: &Parameters, line: usize) -> Result<(), SceneError> {
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

    pub(super) fn shape(&mut self, kind: &str, p: &Parameters, line: usize) -> Result<(), SceneError> {
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
    pub(super) fn emissive(&mut self, material: &str, radiance: [f32; 3], line: usize) -> Result<String, SceneError> {
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

    pub(super) fn emit(&mut self, shape: ObjectShape) {
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

    pub(super) fn finish(mut self) -> Result<Imported, SceneError> {
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
