//! The [`DirectionalDistribution`] trait and the reference uniform distributions.

use core::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::frame::Frame;

/// Hemispherical samplers keep cos θ ≥ this: the 1e-5 band at the horizon is folded onto
/// its edge, so rounding in a change of frame never turns a sample into a direction below
/// the horizon, which its own pdf would call impossible.
pub const MIN_SAMPLED_COS_THETA: f32 = 1e-5;

/// `direction` mirrored across the plane orthogonal to unit `normal`.
#[cfg(any(feature = "mixture", feature = "volume"))]
#[inline]
pub(crate) fn mirror(direction: Vec3, normal: Vec3) -> Vec3 {
    (direction - 2.0 * direction.dot(normal) * normal).normalize()
}

/// A direction drawn over the whole sphere, folded onto unit `normal`'s hemisphere: one
/// below the surface is mirrored across the tangent plane (where it would have found
/// f = 0 and ended the path), and cos θ kept ≥ [`MIN_SAMPLED_COS_THETA`] so rounding in
/// the mirror never leaves it below the horizon that [`folded_pdf`] calls impossible.
#[cfg(any(feature = "mixture", feature = "volume"))]
#[inline]
pub(crate) fn fold_onto_hemisphere(direction: Vec3, normal: Vec3) -> Vec3 {
    let mut direction = direction;
    if direction.dot(normal) < 0.0 {
        direction = mirror(direction, normal);
    }
    let cos_theta = direction.dot(normal);
    if cos_theta < MIN_SAMPLED_COS_THETA {
        direction = (direction + (MIN_SAMPLED_COS_THETA - cos_theta) * normal).normalize();
    }
    direction
}

/// The density of [`fold_onto_hemisphere`]'s directions, per steradian, given the sphere's
/// density `sphere_pdf`: p(ω) + p(mirror ω) above the surface, 0 below it (and for NaN).
/// Exact, and never below the sphere's own density where that is positive.
#[cfg(any(feature = "mixture", feature = "volume"))]
#[inline]
pub(crate) fn folded_pdf(direction: Vec3, normal: Vec3, sphere_pdf: impl Fn(Vec3) -> f32) -> f32 {
    let cos_theta = direction.dot(normal);
    if cos_theta.is_nan() || cos_theta < 0.0 {
        return 0.0;
    }
    sphere_pdf(direction) + sphere_pdf(mirror(direction, normal))
}

/// A sampled direction and the density it was drawn with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionSample {
    /// Unit direction, world space.
    pub direction: Vec3,
    /// Probability density of `direction`, per steradian (solid angle measure).
    pub pdf: f32,
}

/// A probability density over directions, with a sampler that draws from it exactly.
///
/// `pdf(sample(u).direction)` equals `sample(u).pdf` (up to rounding), the density
/// integrates to 1 over the sphere, and it is 0 exactly where `sample` never goes.
pub trait DirectionalDistribution {
    /// Draws a direction from two uniform numbers in [0, 1).
    fn sample(&self, u: Vec2) -> DirectionSample;

    /// The density of `direction` (unit, world space), per steradian.
    fn pdf(&self, direction: Vec3) -> f32;
}

/// Uniform directions over the hemisphere around a normal: pdf 1/(2π) per steradian.
///
/// ```
/// use guiding_core::{DirectionalDistribution, UniformHemisphere};
/// use glam::{Vec2, Vec3};
/// let d = UniformHemisphere::new(Vec3::Y);
/// let s = d.sample(Vec2::new(0.3, 0.7));
/// assert!(s.direction.y >= 0.0);
/// assert_eq!(s.pdf, d.pdf(s.direction));
/// ```
#[derive(Clone, Copy, Debug)]
pub struct UniformHemisphere {
    frame: Frame,
}

impl UniformHemisphere {
    /// The hemisphere on the side `normal` (unit length) points to.
    pub fn new(normal: Vec3) -> Self {
        Self { frame: Frame::from_normal(normal) }
    }
}

impl DirectionalDistribution for UniformHemisphere {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let z = u.x.max(MIN_SAMPLED_COS_THETA);
        let r = libm::sqrtf((1.0 - z * z).max(0.0));
        let phi = 2.0 * PI * u.y;
        let local = Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z);
        DirectionSample { direction: self.frame.to_world(local), pdf: 0.5 / PI }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        if direction.dot(self.frame.normal) >= 0.0 {
            0.5 / PI
        } else {
            0.0
        }
    }
}

/// Uniform directions over the whole sphere: pdf 1/(4π) per steradian.
#[derive(Clone, Copy, Debug, Default)]
pub struct UniformSphere;

impl DirectionalDistribution for UniformSphere {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let z = 1.0 - 2.0 * u.x;
        let r = libm::sqrtf((1.0 - z * z).max(0.0));
        let phi = 2.0 * PI * u.y;
        let direction = Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z);
        DirectionSample { direction, pdf: 0.25 / PI }
    }

    fn pdf(&self, _direction: Vec3) -> f32 {
        0.25 / PI
    }
}
