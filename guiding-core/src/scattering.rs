//! How a guide sees the BSDF when it estimates the integral of Eq. (1).

use core::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

/// The cosine-weighted BSDF `fs(wi, wo)·|cos θi|` at a surface point, as one scalar
/// (a renderer passes luminance or the largest colour channel), per steradian.
///
/// Any `Fn(wi, wo) -> f32` closure is one. A Lambertian BSDF can say so through
/// [`lambertian_albedo`](Self::lambertian_albedo); guides then use exact, precomputed
/// cosine integrals per patch instead of evaluating the closure per patch.
pub trait ScatteringFunction {
    /// `fs(wi, wo)·|cos θi|` for unit world directions `wi` (towards the light) and
    /// `wo` (towards the viewer); 0 where the BSDF does not scatter.
    fn eval_cos(&self, wi: Vec3, wo: Vec3) -> f32;

    /// `Some(albedo)` when the function is `albedo/π · max(0, cos θi)` about the region's
    /// normal; `None` (the default) for anything else.
    fn lambertian_albedo(&self) -> Option<f32> {
        None
    }

    /// A direction `wi` drawn from two uniforms `u` with some density p(wi) > 0 where the
    /// function is non-zero, and its weight `fs(wi, wo)·|cos θi| / p(wi)`; `None` (the
    /// default) when the function cannot sample itself, or when the draw failed (the
    /// estimate is then zero). Used by [`IntegralEstimator::BsdfSampled`](crate::IntegralEstimator::BsdfSampled).
    fn sample_cos(&self, wo: Vec3, u: Vec2) -> Option<SampledDirection> {
        let _ = (wo, u);
        None
    }

    /// Whether [`sample_cos`](Self::sample_cos) is implemented.
    fn can_sample(&self) -> bool {
        false
    }
}

/// A direction drawn by [`ScatteringFunction::sample_cos`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampledDirection {
    /// Unit world direction towards the light.
    pub wi: Vec3,
    /// `fs(wi, wo)·|cos θi| / p(wi)`: the sample's weight.
    pub weight: f32,
}

impl<F: Fn(Vec3, Vec3) -> f32> ScatteringFunction for F {
    fn eval_cos(&self, wi: Vec3, wo: Vec3) -> f32 {
        self(wi, wo)
    }
}

/// A Lambertian (ideal diffuse) reflector with a scalar albedo in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambertian {
    /// Unit shading normal, facing the side light arrives from.
    pub normal: Vec3,
    /// Hemispherical reflectance, in [0, 1].
    pub albedo: f32,
}

impl ScatteringFunction for Lambertian {
    fn eval_cos(&self, wi: Vec3, _wo: Vec3) -> f32 {
        self.albedo * FRAC_1_PI * wi.dot(self.normal).max(0.0)
    }

    fn lambertian_albedo(&self) -> Option<f32> {
        Some(self.albedo)
    }
}
