//! Materials: what a surface does with light, as BSDFs evaluated, sampled and given
//! pdfs in world space around a shading frame.

mod conductor;
mod dielectric;
mod diffuse;
pub mod fresnel;
mod microfacet;
mod plastic;

use glam::{Vec2, Vec3};
use guiding_core::Frame;

pub use fresnel::ComplexIor;
pub use plastic::{Plastic, MIN_COAT_ALPHA};

use crate::texture::Texture;

/// How a surface scatters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Lambertian reflection.
    Diffuse {
        /// Reflectance in \[0, 1\]³.
        albedo: Vec3,
    },
    /// GGX microfacet reflection with Smith shadowing; Fresnel from a complex index of
    /// refraction when one is given.
    Conductor {
        /// Reflectance scale in \[0, 1\]³.
        specular: Vec3,
        /// GGX roughness α; 0 is a perfect mirror.
        alpha: f32,
        /// The conductor's index of refraction; `None` for no Fresnel term.
        ior: Option<ComplexIor>,
    },
    /// Smooth glass: exact Fresnel reflection and refraction.
    Dielectric {
        /// Index of refraction inside relative to outside (the side the normal points to).
        ior: f32,
    },
    /// A thin glass sheet: Fresnel reflection, the rest passing straight through.
    ThinDielectric {
        /// Index of refraction of the sheet relative to the outside.
        ior: f32,
    },
    /// A diffuse base under a rough dielectric coat.
    Plastic(Plastic),
}

/// A surface, the radiance its front face emits, and the textures that vary it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Scattering (with untextured values).
    pub surface: Surface,
    /// Radiance leaving the front face (W·sr⁻¹·m⁻²); zero for non-emitters.
    pub emission: Vec3,
    /// Index of the texture that multiplies the albedo (diffuse, plastic) or the
    /// specular colour (conductor).
    pub albedo_texture: Option<u32>,
    /// Index of the texture giving the opacity (a mask): where it is below one, light
    /// passes through the surface with that probability.
    pub opacity_texture: Option<u32>,
}

/// A direction drawn from a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Incident direction (towards the light), world space.
    pub wi: Vec3,
    /// `f·|cos θi| / pdf`: the throughput factor of this sample.
    pub weight: Vec3,
    /// Density per steradian; for delta lobes, the discrete probability of the lobe.
    pub pdf: f32,
    /// Whether the direction came from a delta (specular) lobe.
    pub delta: bool,
}

/// Where a BSDF is evaluated: the shading frame (z along the normal used for
/// scattering) of a surface point, and the geometric normal on the viewer's side.
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    /// Reflective surfaces: the shading normal turned towards the viewer (two-sided
    /// reflection). Dielectrics: the shading normal on the geometric normal's side
    /// (outside).
    pub frame: Frame,
    /// Reflective surfaces: the geometric normal on the viewer's side; directions below
    /// it are not reflected (shading normals would leak light through the surface).
    /// Dielectrics: the geometric normal as wound.
    pub geometric: Vec3,
}

impl Material {
    /// An untextured material.
    pub fn new(surface: Surface, emission: Vec3) -> Self {
        Self { surface, emission, albedo_texture: None, opacity_texture: None }
    }

    /// This material at a surface point with texture coordinates `uv`: the albedo
    /// texture applied (the opacity is [`opacity`](Self::opacity)'s business).
    pub fn at(&self, textures: &[Texture], uv: Vec2) -> Material {
        let Some(texture) = self.albedo_texture else { return *self };
        let value = textures[texture as usize].eval(uv).clamp(Vec3::ZERO, Vec3::ONE);
        let surface = match self.surface {
            Surface::Diffuse { albedo } => Surface::Diffuse { albedo: albedo * value },
            Surface::Conductor { specular, alpha, ior } => {
                Surface::Conductor { specular: specular * value, alpha, ior }
            }
            Surface::Plastic(plastic) => Surface::Plastic(Plastic { albedo: plastic.albedo * value, ..plastic }),
            other => other,
        };
        Material { surface, ..*self }
    }

    /// Opacity in [0, 1] at `uv`: 1 without an opacity texture.
    pub fn opacity(&self, textures: &[Texture], uv: Vec2) -> f32 {
        self.opacity_texture.map_or(1.0, |t| textures[t as usize].opacity(uv))
    }

    /// Whether every lobe is a delta: such surfaces are neither guided nor lit by NEE.
    pub fn is_delta(&self) -> bool {
        match self.surface {
            Surface::Diffuse { .. } | Surface::Plastic(_) => false,
            Surface::Conductor { alpha, .. } => alpha == 0.0,
            Surface::Dielectric { .. } | Surface::ThinDielectric { .. } => true,
        }
    }

    /// The share of this material's own sampling at `wo` that a guide may take over:
    /// the probability of its lobes that spread light (1 for diffuse surfaces and for
    /// conductors of GGX α at least `min_conductor_alpha`, the base's for plastic, 0 for
    /// smoother conductors and delta surfaces). The rest, a coat's highlight or a narrow
    /// metal lobe, the BSDF samples as well as anything could.
    pub fn guidable_share(&self, shading: &ShadingFrame, wo: Vec3, min_conductor_alpha: f32) -> f32 {
        match self.surface {
            Surface::Diffuse { .. } => 1.0,
            Surface::Conductor { alpha, .. } => (alpha >= min_conductor_alpha) as u32 as f32,
            Surface::Plastic(plastic) => 1.0 - plastic.coat_probability(shading.frame.to_local(wo)),
            Surface::Dielectric { .. } | Surface::ThinDielectric { .. } => 0.0,
        }
    }

    /// Whether the front face emits.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    fn transmits(&self) -> bool {
        matches!(self.surface, Surface::Dielectric { .. } | Surface::ThinDielectric { .. })
    }

    /// The shading frame at a point with unit geometric normal `geometric_normal` and
    /// unit shading normal `shading_normal` (the geometric one where a mesh has none),
    /// seen from direction `wo` (towards the viewer).
    pub fn shading_frame(&self, geometric_normal: Vec3, shading_normal: Vec3, wo: Vec3) -> ShadingFrame {
        let outside = if shading_normal.dot(geometric_normal) < 0.0 { -shading_normal } else { shading_normal };
        if self.transmits() {
            return ShadingFrame { frame: Frame::from_normal(outside), geometric: geometric_normal };
        }
        let side = if geometric_normal.dot(wo) < 0.0 { -1.0 } else { 1.0 };
        let (geometric, shading) = (geometric_normal * side, outside * side);
        // A shading normal that turns away from the viewer would reflect nothing.
        let normal = if shading.dot(wo) > 0.0 { shading } else { geometric };
        ShadingFrame { frame: Frame::from_normal(normal), geometric }
    }

    /// `f(wo, wi)·|cos θi|` for world directions; zero for delta lobes.
    pub fn eval(&self, shading: &ShadingFrame, wo: Vec3, wi: Vec3) -> Vec3 {
        if wi.dot(shading.geometric) <= 0.0 {
            return Vec3::ZERO;
        }
        let (wo, wi) = (shading.frame.to_local(wo), shading.frame.to_local(wi));
        match self.surface {
            Surface::Diffuse { albedo } => diffuse::eval(albedo, wo, wi),
            Surface::Conductor { specular, alpha, ior } => conductor::eval(specular, alpha, ior.as_ref(), wo, wi),
            Surface::Plastic(plastic) => plastic.eval(wo, wi),
            Surface::Dielectric { .. } | Surface::ThinDielectric { .. } => Vec3::ZERO,
        }
    }

    /// Density of sampling `wi` given `wo`, per steradian; zero for delta lobes.
    pub fn pdf(&self, shading: &ShadingFrame, wo: Vec3, wi: Vec3) -> f32 {
        let (wo, wi) = (shading.frame.to_local(wo), shading.frame.to_local(wi));
        match self.surface {
            Surface::Diffuse { .. } => diffuse::pdf(wo, wi),
            Surface::Conductor { alpha, .. } => conductor::pdf(alpha, wo, wi),
            Surface::Plastic(plastic) => plastic.pdf(wo, wi),
            Surface::Dielectric { .. } | Surface::ThinDielectric { .. } => 0.0,
        }
    }

    /// Draws `wi` given `wo` from two uniforms (`u`) plus one for lobe choice.
    pub fn sample(&self, shading: &ShadingFrame, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        let wo_local = shading.frame.to_local(wo);
        let sample = match self.surface {
            Surface::Diffuse { albedo } => diffuse::sample(albedo, wo_local, u),
            Surface::Conductor { specular, alpha, ior } => {
                conductor::sample(specular, alpha, ior.as_ref(), wo_local, u)
            }
            Surface::Plastic(plastic) => plastic.sample(wo_local, u, u_lobe),
            Surface::Dielectric { ior } => dielectric::sample(ior, wo_local, u_lobe),
            Surface::ThinDielectric { ior } => dielectric::sample_thin(ior, wo_local, u_lobe),
        }?;
        let wi = shading.frame.to_world(sample.wi);
        if !self.transmits() && wi.dot(shading.geometric) <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi, ..sample })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shading_normals_never_reflect_through_the_surface() {
        let material = Material::new(Surface::Diffuse { albedo: Vec3::ONE }, Vec3::ZERO);
        let geometric = Vec3::Z;
        let shading = Vec3::new(0.5, 0.0, 0.866).normalize();
        let wo = Vec3::new(-0.3, 0.0, 0.95).normalize();
        let frame = material.shading_frame(geometric, shading, wo);
        // Above the shading hemisphere but below the geometric one: no reflection.
        let below = Vec3::new(0.95, 0.0, -0.1).normalize();
        assert!(below.dot(frame.frame.normal) > 0.0);
        assert_eq!(material.eval(&frame, wo, below), Vec3::ZERO);
        let mut rng = guiding_core::Pcg32::new(4, 4);
        for _ in 0..10_000 {
            if let Some(s) = material.sample(&frame, wo, rng.next_vec2(), rng.next_f32()) {
                assert!(s.wi.dot(geometric) > 0.0);
            }
        }
        // Seen from below the shading normal's hemisphere, the geometric normal shades.
        let grazing = Vec3::new(-0.99, 0.0, 0.1).normalize();
        assert_eq!(material.shading_frame(geometric, shading, grazing).frame.normal, geometric);
    }

    #[test]
    fn guides_may_take_the_diffuse_share_of_the_sampling_only() {
        let frame = ShadingFrame { frame: Frame::from_normal(Vec3::Z), geometric: Vec3::Z };
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let diffuse = Material::new(Surface::Diffuse { albedo: Vec3::splat(0.5) }, Vec3::ZERO);
        assert_eq!(diffuse.guidable_share(&frame, wo, 0.0), 1.0);
        let glass = Material::new(Surface::Dielectric { ior: 1.5 }, Vec3::ZERO);
        assert_eq!(glass.guidable_share(&frame, wo, 0.0), 0.0);
        let coat = Plastic::new(Vec3::splat(0.5), 1.0, 1.5, 0.1);
        let plastic = Material::new(Surface::Plastic(coat), Vec3::ZERO);
        let share = plastic.guidable_share(&frame, wo, 0.0);
        assert!((share - (1.0 - coat.coat_probability(wo))).abs() < 1e-6 && share > 0.0 && share < 1.0, "{share}");
        // Conductors are guided from a roughness on, smoother ones not at all.
        let metal = |alpha| Material::new(Surface::Conductor { specular: Vec3::ONE, alpha, ior: None }, Vec3::ZERO);
        assert_eq!(metal(0.1).guidable_share(&frame, wo, 0.3), 0.0);
        assert_eq!(metal(0.3).guidable_share(&frame, wo, 0.3), 1.0);
        assert_eq!(metal(0.1).guidable_share(&frame, wo, 0.0), 1.0);
        // At grazing angles the coat reflects more, and takes more of the sampling.
        assert!(plastic.guidable_share(&frame, Vec3::new(0.99, 0.0, 0.14).normalize(), 0.0) < share);
    }

    #[test]
    fn textures_scale_the_albedo() {
        let checks = Texture::checkerboard(Vec3::splat(0.5), Vec3::ONE);
        let mut material = Material::new(Surface::Diffuse { albedo: Vec3::splat(0.8) }, Vec3::ZERO);
        material.albedo_texture = Some(0);
        let at = material.at(std::slice::from_ref(&checks), Vec2::new(0.5, 0.5));
        assert_eq!(at.surface, Surface::Diffuse { albedo: Vec3::splat(0.4) });
        assert_eq!(material.opacity(&[checks], Vec2::ZERO), 1.0);
    }
}
