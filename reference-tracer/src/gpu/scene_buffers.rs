//! A scene as the flat arrays the shader reads (see `shader/header.wgsl`'s bindings): built once, then
//! uploaded as storage buffers.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use crate::material::Surface;
use crate::scene::Scene;

/// `GpuMaterial::kind` of each surface the shader has (its DIFFUSE, CONDUCTOR, …).
pub(super) const MATERIAL_DIFFUSE: u32 = 0;
pub(super) const MATERIAL_CONDUCTOR: u32 = 1;
pub(super) const MATERIAL_DIELECTRIC: u32 = 2;
pub(super) const MATERIAL_THIN_DIELECTRIC: u32 = 3;

/// `shader/header.wgsl`'s `Material`: 80 bytes.
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
struct GpuMaterial {
    kind: u32,
    alpha: f32,
    ior: f32,
    fresnel: u32,
    albedo: [f32; 4],
    emission: [f32; 4],
    eta: [f32; 4],
    k: [f32; 4],
}

/// `shader/header.wgsl`'s `Light`: 64 bytes.
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
struct GpuLight {
    v0: [f32; 4],
    v1: [f32; 4],
    /// w: area.
    v2: [f32; 4],
    /// w: selection probability.
    emission: [f32; 4],
}

/// `shader/header.wgsl`'s `Node` (guiding-obvhs's `FlatBvhNode`): 32 bytes.
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
struct GpuNode {
    min: [f32; 3],
    first: u32,
    max: [f32; 3],
    count: u32,
}

/// The arrays, on the host.
pub struct SceneBuffers {
    nodes: Vec<GpuNode>,
    triangles: Vec<[f32; 4]>,
    triangle_info: Vec<[f32; 4]>,
    light_of_triangle: Vec<u32>,
    materials: Vec<GpuMaterial>,
    lights: Vec<GpuLight>,
    light_cdf: Vec<f32>,
}

/// The same arrays on a device.
pub struct UploadedScene {
    pub nodes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    pub triangle_info: wgpu::Buffer,
    pub light_of_triangle: wgpu::Buffer,
    pub materials: wgpu::Buffer,
    pub lights: wgpu::Buffer,
    pub light_cdf: wgpu::Buffer,
}

/// What in `scene`'s materials or geometry the GPU tracer cannot render, if anything.
pub fn unsupported_material(scene: &Scene) -> Option<String> {
    if !scene.vertex_normals.is_empty() {
        return Some("shading normals (vertex normals)".into());
    }
    for (material, name) in scene.materials.iter().zip(&scene.material_names) {
        if matches!(material.surface, Surface::Plastic(_)) {
            return Some(format!("plastic (material \"{name}\")"));
        }
        if material.opacity_texture.is_some() || material.albedo_texture.is_some() {
            return Some(format!("textures (material \"{name}\")"));
        }
    }
    None
}

/// One element where an array would be empty: bindings cannot be zero-sized.
fn non_empty<T: Default>(mut values: Vec<T>) -> Vec<T> {
    if values.is_empty() {
        values.push(T::default());
    }
    values
}

impl SceneBuffers {
    /// The arrays of `scene`; `unsupported_material` must have found nothing.
    pub fn new(scene: &Scene) -> Result<Self, String> {
        let bvh = guiding_obvhs::flat_bvh2(&scene.triangles);
        let nodes =
            bvh.nodes.iter().map(|n| GpuNode { min: n.min, first: n.first, max: n.max, count: n.count }).collect();
        let triangles = bvh
            .triangles
            .iter()
            .zip(&bvh.original_index)
            .flat_map(|(&[a, b, c], &index)| [a.extend(f32::from_bits(index)), b.extend(0.0), c.extend(0.0)])
            .map(|v| v.to_array())
            .collect();
        let triangle_info = scene
            .normals
            .iter()
            .zip(&scene.triangle_materials)
            .map(|(n, &material)| n.extend(f32::from_bits(material)).to_array())
            .collect();
        let light_of_triangle =
            (0..scene.triangles.len() as u32).map(|t| scene.lights.light_of_triangle(t).unwrap_or(u32::MAX)).collect();
        let materials = scene
            .materials
            .iter()
            .map(|m| {
                let emission = m.emission.extend(0.0).to_array();
                match m.surface {
                    Surface::Diffuse { albedo } => GpuMaterial {
                        kind: MATERIAL_DIFFUSE,
                        albedo: albedo.extend(0.0).to_array(),
                        emission,
                        ..Default::default()
                    },
                    Surface::Conductor { specular, alpha, ior } => GpuMaterial {
                        kind: MATERIAL_CONDUCTOR,
                        alpha,
                        fresnel: ior.is_some() as u32,
                        albedo: specular.extend(0.0).to_array(),
                        emission,
                        eta: ior.map_or([0.0; 4], |i| i.eta.extend(0.0).to_array()),
                        k: ior.map_or([0.0; 4], |i| i.k.extend(0.0).to_array()),
                        ior: 0.0,
                    },
                    Surface::Dielectric { ior } => {
                        GpuMaterial { kind: MATERIAL_DIELECTRIC, ior, emission, ..Default::default() }
                    }
                    Surface::ThinDielectric { ior } => {
                        GpuMaterial { kind: MATERIAL_THIN_DIELECTRIC, ior, emission, ..Default::default() }
                    }
                    Surface::Plastic(_) => GpuMaterial::default(),
                }
            })
            .collect();
        let lights = (0..scene.lights.len() as u32)
            .map(|light| {
                let (triangle, emission, area) = scene.lights.light(light);
                let [a, b, c] = scene.triangles[triangle as usize].vertices;
                GpuLight {
                    v0: a.extend(0.0).to_array(),
                    v1: b.extend(0.0).to_array(),
                    v2: c.extend(area).to_array(),
                    emission: emission.extend(scene.lights.power_probability(light)).to_array(),
                }
            })
            .collect();
        Ok(Self {
            nodes,
            triangles,
            triangle_info,
            light_of_triangle,
            materials,
            lights,
            light_cdf: scene.lights.power_cdf().to_vec(),
        })
    }

    /// Uploads every array as a read-only storage buffer.
    pub fn uploaded(&self, device: &wgpu::Device) -> UploadedScene {
        let storage = |label: &str, bytes: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        // A scene always has a triangle, so the node list is never padded.
        UploadedScene {
            nodes: storage("nodes", bytemuck::cast_slice(&non_empty(self.nodes.clone()))),
            triangles: storage("triangles", bytemuck::cast_slice(&non_empty(self.triangles.clone()))),
            triangle_info: storage("triangle info", bytemuck::cast_slice(&non_empty(self.triangle_info.clone()))),
            light_of_triangle: storage(
                "light of triangle",
                bytemuck::cast_slice(&non_empty(self.light_of_triangle.clone())),
            ),
            materials: storage("materials", bytemuck::cast_slice(&non_empty(self.materials.clone()))),
            lights: storage("lights", bytemuck::cast_slice(&non_empty(self.lights.clone()))),
            light_cdf: storage("light cdf", bytemuck::cast_slice(&non_empty(self.light_cdf.clone()))),
        }
    }
}
