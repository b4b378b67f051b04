//! [`VmfLobe`]: a von Mises–Fisher distribution on the unit sphere, evaluated and sampled
//! in forms that stay finite from κ = 0 (uniform) to the largest κ allowed.

use core::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::frame::Frame;

/// Concentrations below this are treated as zero: the lobe is uniform over the sphere.
pub const MIN_CONCENTRATION: f32 = 1e-4;

/// The largest concentration a lobe may have (an angular width of about 0.6°): beyond it
/// the density's peak (κ/2π) and the f32 precision of directions part ways.
pub const MAX_CONCENTRATION: f32 = 1e4;

/// A von Mises–Fisher lobe: density κ·e^{κ(μ·ω − 1)} / (2π(1 − e^{−2κ})) per steradian
/// about the unit mean direction μ.
///
/// ```
/// use guiding_core::mixture::VmfLobe;
/// use glam::{Vec2, Vec3};
/// let lobe = VmfLobe::new(Vec3::Y, 50.0);
/// let d = lobe.sample(Vec2::new(0.3, 0.6));
/// assert!(d.y > 0.5 && lobe.pdf(d) > lobe.pdf(-Vec3::Y));
/// // κ = 0 is the uniform sphere.
/// assert!((VmfLobe::new(Vec3::X, 0.0).pdf(Vec3::Z) - 0.25 / std::f32::consts::PI).abs() < 1e-7);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VmfLobe {
    mean: Vec3,
    concentration: f32,
    /// κ / (2π(1 − e^{−2κ})), or 1/4π for a uniform lobe.
    normalization: f32,
}

impl VmfLobe {
    /// A lobe about `mean` (normalised here; a zero or non-finite mean gives +z) with
    /// concentration `concentration` clamped to [0, [`MAX_CONCENTRATION`]] (NaN → 0).
    pub fn new(mean: Vec3, concentration: f32) -> Self {
        Self::with_unit_mean(mean.try_normalize().unwrap_or(Vec3::Z), concentration)
    }

    /// [`new`](Self::new) for a mean the caller knows is unit length, kept bit for bit
    /// (a decoded lobe then encodes to the same bytes).
    pub(crate) fn with_unit_mean(mean: Vec3, concentration: f32) -> Self {
        let kappa = if concentration.is_nan() { 0.0 } else { concentration.clamp(0.0, MAX_CONCENTRATION) };
        let kappa = if kappa < MIN_CONCENTRATION { 0.0 } else { kappa };
        // 1 − e^{−2κ} as −expm1(−2κ): exact to f32 precision even where it is ≈ 2κ.
        let normalization = if kappa == 0.0 { 0.25 / PI } else { kappa / (2.0 * PI * -libm::expm1f(-2.0 * kappa)) };
        Self { mean, concentration: kappa, normalization }
    }

    /// The unit mean direction μ.
    pub fn mean(&self) -> Vec3 {
        self.mean
    }

    /// The concentration κ.
    pub fn concentration(&self) -> f32 {
        self.concentration
    }

    /// The density at the mean, C(κ) = κ / (2π(1 − e^{−2κ}))
    /// (1/4π at κ = 0), per steradian: `pdf(d) = C(κ)·e^{κ(μ·d − 1)}`.
    pub fn normalization(&self) -> f32 {
        self.normalization
    }

    /// Density of unit direction `d`, per steradian. μ·d − 1 is taken as −|d − μ|²/2,
    /// which keeps its precision where μ·d rounds to 1.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        if self.concentration == 0.0 {
            return self.normalization;
        }
        let cos_minus_one = -0.5 * (d - self.mean).length_squared();
        self.normalization * libm::expf(self.concentration * cos_minus_one)
    }

    /// A direction from two uniform numbers in [0, 1) (Jakob, "Numerically stable sampling
    /// of the von Mises–Fisher distribution on S²", 2012).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let w = if self.concentration == 0.0 {
            1.0 - 2.0 * u.x
        } else {
            // w = 1 + ln(u + (1 − u)e^{−2κ})/κ, with the logarithm's argument written as
            // 1 + (1 − u)(e^{−2κ} − 1) so neither end loses precision.
            let log = libm::log1pf((1.0 - u.x) * libm::expm1f(-2.0 * self.concentration));
            (1.0 + log / self.concentration).clamp(-1.0, 1.0)
        };
        let radius = libm::sqrtf((1.0 - w * w).max(0.0));
        let (sin_phi, cos_phi) = libm::sincosf(2.0 * PI * u.y);
        Frame::from_normal(self.mean).to_world(Vec3::new(radius * cos_phi, radius * sin_phi, w)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::{DirectionSample, DirectionalDistribution};
    use crate::validation::{chi_square_test, pdf_integral, ChiSquareSettings};

    impl DirectionalDistribution for VmfLobe {
        fn sample(&self, u: Vec2) -> DirectionSample {
            let direction = VmfLobe::sample(self, u);
            DirectionSample { direction, pdf: VmfLobe::pdf(self, direction) }
        }
        fn pdf(&self, direction: Vec3) -> f32 {
            VmfLobe::pdf(self, direction)
        }
    }

    #[test]
    fn integrates_to_one_and_matches_its_sampler_across_concentrations() {
        for kappa in [0.0, 1e-6, 0.01, 1.0, 10.0, 200.0] {
            let lobe = VmfLobe::new(Vec3::new(0.3, -0.5, 0.8), kappa);
            let total = pdf_integral(&|d| lobe.pdf(d), lobe.mean(), 32, 5);
            assert!((total - 1.0).abs() < 2e-3, "κ {kappa}: ∫ = {total}");
            let settings = ChiSquareSettings { theta_bins: 24, phi_bins: 48, samples: 400_000, ..Default::default() };
            let report = chi_square_test(&lobe, lobe.mean(), &settings);
            assert!(report.passes(0.01), "κ {kappa}: {report:?}");
        }
    }

    #[test]
    fn extreme_concentrations_stay_finite() {
        for kappa in [0.0, 1e-30, MIN_CONCENTRATION, 1e3, MAX_CONCENTRATION, 1e30, f32::INFINITY, f32::NAN, -5.0] {
            let lobe = VmfLobe::new(Vec3::new(1.0, 2.0, 3.0), kappa);
            for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::splat(1.0 - f32::EPSILON)] {
                let d = lobe.sample(u);
                assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-5, "κ {kappa}, u {u}: {d}");
                let p = lobe.pdf(d);
                assert!(p.is_finite() && p >= 0.0, "κ {kappa}: pdf {p}");
            }
            assert!(lobe.pdf(-lobe.mean()).is_finite());
        }
        // A degenerate mean falls back to +z.
        assert_eq!(VmfLobe::new(Vec3::ZERO, 1.0).mean(), Vec3::Z);
        assert_eq!(VmfLobe::new(Vec3::NAN, 1.0).mean(), Vec3::Z);
    }
}
