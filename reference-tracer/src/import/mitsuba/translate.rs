//! Mitsuba's shapes and emitters as the project's shapes, emissive materials and
//! environment, and the finished description.

use glam::{Mat3, Mat4, Vec3};
use roxmltree::Node;

use super::super::primitives::{primitive_shape, Primitive};
use super::{Reader, Value};
use crate::import::{rows_of, Imported};
use crate::scene::{EnvironmentDescription, MaterialDescription, SceneDescription, SceneError, ShapeDescription};

impl<'input> Reader<'_, 'input> {
    pub(super) fn shape(&mut self, node: Node) -> Result<(), SceneError> {
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
    pub(super) fn emissive(&mut self, material: &str, radiance: [f32; 3], line: usize) -> String {
        let emitting = self.materials[material].emitting(radiance);
        let name = format!("emitter-line-{line}");
        self.materials.insert(name.clone(), emitting);
        name
    }

    pub(super) fn emitter(&mut self, node: Node) -> Result<(), SceneError> {
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

    pub(super) fn finish(mut self) -> Result<Imported, SceneError> {
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
