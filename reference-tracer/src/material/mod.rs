//! Materials: what a surface does with light, as BSDFs evaluated, sampled and given
//! pdfs in world space around a shading frame.

mod conductor;
mod dielectric;
mod diffuse;

use glam::{Vec2, Vec3};
use guiding_core::Frame;

/// How a surface scatters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Lambertian reflection.
    Diffuse {
        /// Reflectance in \[0, 1\]³.
        albedo: Vec3,
    },
    /// GGX microfacet reflection with Smith shadowing, no Fresnel.
    Conductor {
        /// Reflectance scale in \[0, 1\]³.
        specular: Vec3,
        /// GGX roughness α; 0 is a perfect mirror.
        alpha: f32,
    },
    /// Smooth glass: exact Fresnel reflection and refraction.
    Dielectric {
        /// Index of refraction inside relative to outside (the side the normal points to).
        ior: f32,
    },
}

/// A surface and the radiance its front face emits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Scattering.
    pub surface: Surface,
    /// Radiance leaving the front face (W·sr⁻¹·m⁻²); zero for non-emitters.
    pub emission: Vec3,
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
/// scattering) of a surface point.
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    /// Reflective surfaces: the normal turned towards the viewer (two-sided
    /// reflection). Dielectrics: the geometric normal as wound (outside).
    pub frame: Frame,
}

impl Material {
    /// Whether every lobe is a delta: such surfaces are neither guided nor lit by NEE.
    pub fn is_delta(&self) -> bool {
        match self.surface {
            Surface::Diffuse { .. } => false,
            Surface::Conductor { alpha, .. } => alpha == 0.0,
            Surface::Dielectric { .. } => true,
        }
    }

    /// Whether the front face emits.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// The shading frame at a point with unit geometric normal `geometric_normal`, seen
    /// from direction `wo` (towards the viewer).
    pub fn shading_frame(&self, geometric_normal: Vec3, wo: Vec3) -> ShadingFrame {
        let normal = match self.surface {
            Surface::Dielectric { .. } => geometric_normal,
            _ if geometric_normal.dot(wo) < 0.0 => -geometric_normal,
            _ => geometric_normal,
        };
        ShadingFrame { frame: Frame::from_normal(normal) }
    }

    /// `f(wo, wi)·|cos θi|` for world directions; zero for delta lobes.
    pub fn eval(&self, shading: &ShadingFrame, wo: Vec3, wi: Vec3) -> Vec3 {
        let (wo, wi) = (shading.frame.to_local(wo), shading.frame.to_local(wi));
        match self.surface {
            Surface::Diffuse { albedo } => diffuse::eval(albedo, wo, wi),
            Surface::Conductor { specular, alpha } => conductor::eval(specular, alpha, wo, wi),
            Surface::Dielectric { .. } => Vec3::ZERO,
        }
    }

    /// Density of sampling `wi` given `wo`, per steradian; zero for delta lobes.
    pub fn pdf(&self, shading: &ShadingFrame, wo: Vec3, wi: Vec3) -> f32 {
        let (wo, wi) = (shading.frame.to_local(wo), shading.frame.to_local(wi));
        match self.surface {
            Surface::Diffuse { .. } => diffuse::pdf(wo, wi),
            Surface::Conductor { alpha, .. } => conductor::pdf(alpha, wo, wi),
            Surface::Dielectric { .. } => 0.0,
        }
    }

    /// Draws `wi` given `wo` from two uniforms (`u`) plus one for lobe choice.
    pub fn sample(&self, shading: &ShadingFrame, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        let wo_local = shading.frame.to_local(wo);
        let sample = match self.surface {
            Surface::Diffuse { albedo } => diffuse::sample(albedo, wo_local, u),
            Surface::Conductor { specular, alpha } => conductor::sample(specular, alpha, wo_local, u),
            Surface::Dielectric { ior } => dielectric::sample(ior, wo_local, u_lobe),
        }?;
        Some(BsdfSample { wi: shading.frame.to_world(sample.wi), ..sample })
    }
}
