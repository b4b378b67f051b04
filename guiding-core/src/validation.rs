//! Statistical validation of directional distributions: the pdf's integral and a
//! chi-square goodness-of-fit test of the sampler against the pdf (pbrt-v4 style).
//!
//! Part of the public API so renderers can check their own distributions, and so every
//! [`Guide`](crate::Guide) is tested by one harness.

use core::f64::consts::PI;

use alloc::vec;
use alloc::vec::Vec;
use glam::{Vec2, Vec3};

use crate::distribution::DirectionalDistribution;
use crate::frame::Frame;
use crate::low_discrepancy::Pcg32;

/// The direction at (z = cos θ, φ) in `frame`.
fn direction(frame: &Frame, z: f64, phi: f64) -> Vec3 {
    let r = libm::sqrt((1.0 - z * z).max(0.0));
    frame.to_world(Vec3::new((r * libm::cos(phi)) as f32, (r * libm::sin(phi)) as f32, z as f32))
}

/// ∫ pdf dω over the rectangle `z0..z1 × phi0..phi1` of (cos θ, φ) in `frame` (dω = dz dφ).
///
/// Adaptive: the rectangle is first split into 4×4 (so a small feature of the pdf, a
/// sliver of a dense cell clipping a corner, is not missed by one coarse grid); then a
/// part whose 5×5 grid of pdf values (edges included) is constant counts as constant;
/// otherwise it is split in four, until `max_depth` levels or until
/// its spread of values times its area is at most `tolerance` (an absolute bound on the
/// leaf's error, in probability), where the midpoint rule over its four quarters takes
/// over. Those midpoints are interior, so
/// a discontinuity on a rectangle's edge (the horizon, a patch border) is never sampled
/// at the last level. Piecewise-constant pdfs (tables of patches) are integrated exactly
/// away from their borders; along them the error halves per level, and a border that
/// clips a corner between grid points unseen costs at most 1/32 of a rectangle.
pub fn integrate_rectangle(
    pdf: &impl Fn(Vec3) -> f32,
    frame: &Frame,
    (z0, z1): (f64, f64),
    (phi0, phi1): (f64, f64),
    tolerance: f64,
    max_depth: u32,
) -> f64 {
    integrate_adaptively(pdf, frame, (z0, z1), (phi0, phi1), tolerance, max_depth, MIN_SPLITS)
}

/// Levels [`integrate_rectangle`] always splits, within its depth limit.
const MIN_SPLITS: u32 = 2;

/// [`integrate_rectangle`], splitting at least `splits` more levels.
fn integrate_adaptively(
    pdf: &impl Fn(Vec3) -> f32,
    frame: &Frame,
    (z0, z1): (f64, f64),
    (phi0, phi1): (f64, f64),
    tolerance: f64,
    max_depth: u32,
    splits: u32,
) -> f64 {
    let (zm, phim) = (0.5 * (z0 + z1), 0.5 * (phi0 + phi1));
    if splits > 0 && max_depth > 0 {
        let (depth, splits) = (max_depth - 1, splits - 1);
        return integrate_adaptively(pdf, frame, (z0, zm), (phi0, phim), tolerance, depth, splits)
            + integrate_adaptively(pdf, frame, (z0, zm), (phim, phi1), tolerance, depth, splits)
            + integrate_adaptively(pdf, frame, (zm, z1), (phi0, phim), tolerance, depth, splits)
            + integrate_adaptively(pdf, frame, (zm, z1), (phim, phi1), tolerance, depth, splits);
    }
    let (mut low, mut high) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..25 {
        let z = z0 + (z1 - z0) * (i / 5) as f64 * 0.25;
        let phi = phi0 + (phi1 - phi0) * (i % 5) as f64 * 0.25;
        let value = pdf(direction(frame, z, phi));
        low = low.min(value);
        high = high.max(value);
    }
    let area = (z1 - z0) * (phi1 - phi0);
    if low == high {
        return area * low as f64;
    }
    if max_depth == 0 || (high - low) as f64 * area <= tolerance {
        let (dz, dphi) = (0.25 * (z1 - z0), 0.25 * (phi1 - phi0));
        let quarters = [(zm - dz, phim - dphi), (zm - dz, phim + dphi), (zm + dz, phim - dphi), (zm + dz, phim + dphi)];
        let sum: f64 = quarters.iter().map(|&(z, phi)| pdf(direction(frame, z, phi)) as f64).sum();
        return area * 0.25 * sum;
    }
    let depth = max_depth - 1;
    integrate_adaptively(pdf, frame, (z0, zm), (phi0, phim), tolerance, depth, 0)
        + integrate_adaptively(pdf, frame, (z0, zm), (phim, phi1), tolerance, depth, 0)
        + integrate_adaptively(pdf, frame, (zm, z1), (phi0, phim), tolerance, depth, 0)
        + integrate_adaptively(pdf, frame, (zm, z1), (phim, phi1), tolerance, depth, 0)
}

/// ∫ pdf dω over the whole sphere (should be 1), on a `cells × 2·cells` grid of
/// (cos θ, φ) rectangles about `normal`, each integrated adaptively to `max_depth` levels.
pub fn pdf_integral(pdf: &impl Fn(Vec3) -> f32, normal: Vec3, cells: u32, max_depth: u32) -> f64 {
    let frame = Frame::from_normal(normal);
    let (nz, nphi) = (cells, 2 * cells);
    let mut total = 0.0;
    for i in 0..nz {
        let z = (-1.0 + 2.0 * i as f64 / nz as f64, -1.0 + 2.0 * (i + 1) as f64 / nz as f64);
        for j in 0..nphi {
            let phi = (2.0 * PI * j as f64 / nphi as f64, 2.0 * PI * (j + 1) as f64 / nphi as f64);
            total += integrate_rectangle(pdf, &frame, z, phi, 0.0, max_depth);
        }
    }
    total
}

/// Parameters of [`chi_square_test`].
#[derive(Clone, Copy, Debug)]
pub struct ChiSquareSettings {
    /// Histogram bins in θ ∈ [0, π] (about the test's axis).
    pub theta_bins: u32,
    /// Histogram bins in φ ∈ [0, 2π).
    pub phi_bins: u32,
    /// Number of samples drawn.
    pub samples: u32,
    /// Cells expecting fewer samples are pooled until the pool expects this many.
    pub min_expected: f64,
    /// Largest error, in samples, allowed in the expected count of any one leaf of the
    /// adaptive integration (the leaves along a border add up, with varying signs).
    pub leaf_tolerance: f64,
    /// Seed of the uniform numbers fed to the sampler.
    pub seed: u64,
}

impl Default for ChiSquareSettings {
    fn default() -> Self {
        Self { theta_bins: 32, phi_bins: 64, samples: 1_000_000, min_expected: 5.0, leaf_tolerance: 0.05, seed: 1 }
    }
}

/// The outcome of a chi-square test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChiSquareReport {
    /// Samples drawn.
    pub samples: u64,
    /// The χ² statistic over pooled cells.
    pub statistic: f64,
    /// Degrees of freedom (pooled cells − 1).
    pub degrees_of_freedom: u32,
    /// Probability of a statistic at least this large if the sampler matches the pdf.
    pub p_value: f64,
    /// Samples that landed in cells where the pdf integrates to zero.
    pub samples_in_zero_cells: u64,
    /// Samples whose direction is not finite and unit length, or whose reported pdf is not
    /// positive, finite and equal (to 1e-3 relative) to `pdf(direction)`.
    pub inconsistent_samples: u64,
}

impl ChiSquareReport {
    /// Whether the sampler passes at significance level `significance` (per test): the
    /// p-value is at least that, no sample fell where the pdf integrates to zero, and at
    /// most 1 in 10⁵ samples disagrees with `pdf` — the rounding allowance for directions
    /// on a border between two pieces of a piecewise-constant pdf, where a sampler and its
    /// pdf may each pick a different side.
    pub fn passes(&self, significance: f64) -> bool {
        self.p_value >= significance
            && self.samples_in_zero_cells == 0
            && self.inconsistent_samples * 100_000 <= self.samples
    }
}

/// The per-test significance that keeps the chance of any false failure among `tests`
/// independent tests at `overall` (Šidák correction).
pub fn sidak_significance(overall: f64, tests: u32) -> f64 {
    1.0 - libm::pow(1.0 - overall, 1.0 / tests as f64)
}

/// Draws `settings.samples` directions from `distribution`, bins them over a θ×φ grid
/// about `axis`, and compares the counts with the pdf's integral over each cell.
pub fn chi_square_test<D: DirectionalDistribution>(
    distribution: &D,
    axis: Vec3,
    settings: &ChiSquareSettings,
) -> ChiSquareReport {
    let frame = Frame::from_normal(axis);
    let (nt, np) = (settings.theta_bins as usize, settings.phi_bins as usize);
    let mut observed = vec![0u64; nt * np];
    let mut inconsistent = 0u64;
    let mut rng = Pcg32::new(settings.seed, 0x5eed);
    for _ in 0..settings.samples {
        let sample = distribution.sample(Vec2::new(rng.next_f32(), rng.next_f32()));
        let d = sample.direction;
        let pdf = distribution.pdf(d);
        let consistent = d.is_finite()
            && (d.length() - 1.0).abs() < 1e-4
            && sample.pdf.is_finite()
            && sample.pdf > 0.0
            && (pdf - sample.pdf).abs() <= 1e-3 * sample.pdf;
        if !consistent {
            inconsistent += 1;
            continue;
        }
        // Binned in f64: near the horizon θ differs from π/2 by less than f32 resolves.
        let local = frame.to_local(d);
        let theta = libm::acos((local.z as f64).clamp(-1.0, 1.0));
        let mut phi = libm::atan2(local.y as f64, local.x as f64);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let i = ((theta / PI * nt as f64) as usize).min(nt - 1);
        let j = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
        observed[i * np + j] += 1;
    }

    let pdf = |d: Vec3| distribution.pdf(d);
    let mut cells: Vec<(f64, u64)> = Vec::with_capacity(nt * np);
    for i in 0..nt {
        let (t0, t1) = (PI * i as f64 / nt as f64, PI * (i + 1) as f64 / nt as f64);
        let z = (libm::cos(t1), libm::cos(t0));
        for j in 0..np {
            let phi = (2.0 * PI * j as f64 / np as f64, 2.0 * PI * (j + 1) as f64 / np as f64);
            let tolerance = settings.leaf_tolerance / settings.samples as f64;
            let probability = integrate_rectangle(&pdf, &frame, z, phi, tolerance, 16);
            cells.push((probability * settings.samples as f64, observed[i * np + j]));
        }
    }
    pooled_chi_square(cells, settings.min_expected, settings.samples as u64, inconsistent)
}

/// Chi-square of a discrete sampler: `probabilities[k]` is the claimed probability of
/// outcome k, `observed[k]` how often `samples` draws produced it. Cells expected fewer
/// than `min_expected` times are pooled (smallest first).
pub fn discrete_chi_square(probabilities: &[f64], observed: &[u64], min_expected: f64) -> ChiSquareReport {
    let samples: u64 = observed.iter().sum();
    let cells = probabilities.iter().zip(observed).map(|(&p, &o)| (p * samples as f64, o)).collect();
    pooled_chi_square(cells, min_expected, samples, 0)
}

/// The statistic over (expected, observed) cells, pooling those expected fewer than
/// `min_expected` times; samples in cells of zero expectation are counted apart.
fn pooled_chi_square(
    mut cells: Vec<(f64, u64)>,
    min_expected: f64,
    samples: u64,
    inconsistent: u64,
) -> ChiSquareReport {
    cells.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut statistic = 0.0;
    let mut bins = 0u32;
    let mut zero_cells = 0u64;
    let (mut pool_expected, mut pool_observed) = (0.0f64, 0u64);
    for &(expected, observed) in &cells {
        if expected <= 0.0 {
            zero_cells += observed;
            continue;
        }
        if expected < min_expected {
            pool_expected += expected;
            pool_observed += observed;
            if pool_expected >= min_expected {
                statistic += square(pool_observed as f64 - pool_expected) / pool_expected;
                bins += 1;
                pool_expected = 0.0;
                pool_observed = 0;
            }
            continue;
        }
        statistic += square(observed as f64 - expected) / expected;
        bins += 1;
    }
    if pool_expected > 0.0 {
        statistic += square(pool_observed as f64 - pool_expected) / pool_expected;
        bins += 1;
    }
    let degrees_of_freedom = bins.saturating_sub(1).max(1);
    ChiSquareReport {
        samples,
        statistic,
        degrees_of_freedom,
        p_value: chi_square_survival(statistic, degrees_of_freedom),
        samples_in_zero_cells: zero_cells,
        inconsistent_samples: inconsistent,
    }
}

fn square(x: f64) -> f64 {
    x * x
}

/// P(X ≥ x) for X ~ χ²(k): the regularised upper incomplete gamma Q(k/2, x/2).
pub fn chi_square_survival(x: f64, degrees_of_freedom: u32) -> f64 {
    regularized_gamma_q(degrees_of_freedom as f64 / 2.0, x / 2.0)
}

/// Q(a, x) = Γ(a, x)/Γ(a), by the series for x < a + 1 and Lentz's continued fraction
/// otherwise (Numerical Recipes §6.2).
fn regularized_gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let log_prefactor = a * libm::log(x) - x - libm::lgamma(a);
    if x < a + 1.0 {
        let (mut term, mut sum, mut denominator) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            denominator += 1.0;
            term *= x / denominator;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        (1.0 - sum * libm::exp(log_prefactor)).clamp(0.0, 1.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (libm::exp(log_prefactor) * h).clamp(0.0, 1.0)
    }
}

/// Draws a direction from the mixture `p_guide`·`distribution` + (1 − `p_guide`)·cosine
/// about +z, as a renderer mixing guide and a Lambertian BSDF would; returns it with the
/// mixture's pdf (per steradian). For testing that what a guide learns through
/// `update_sampled` does not depend on `p_guide`.
pub fn sample_guide_or_cosine<D: DirectionalDistribution + ?Sized>(
    distribution: &D,
    p_guide: f32,
    rng: &mut Pcg32,
) -> (Vec3, f32) {
    let u = rng.next_vec2();
    let wi = if rng.next_f32() < p_guide {
        distribution.sample(u).direction
    } else {
        let (r, phi) = (libm::sqrtf(u.x), 2.0 * core::f32::consts::PI * u.y);
        Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), libm::sqrtf(1.0 - u.x))
    };
    let cosine = wi.z.max(0.0) * core::f32::consts::FRAC_1_PI;
    (wi, p_guide * distribution.pdf(wi) + (1.0 - p_guide) * cosine)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::{DirectionSample, UniformHemisphere, UniformSphere};

    #[test]
    fn chi_square_survival_matches_tables() {
        // Critical values: P(χ²(1) ≥ 3.841) = 0.05, P(χ²(10) ≥ 23.209) = 0.01,
        // P(χ²(100) ≥ 135.807) = 0.01.
        assert!((chi_square_survival(3.841, 1) - 0.05).abs() < 1e-4);
        assert!((chi_square_survival(23.209, 10) - 0.01).abs() < 1e-4);
        assert!((chi_square_survival(135.807, 100) - 0.01).abs() < 1e-4);
        assert!((chi_square_survival(2.0, 2) - libm::exp(-1.0)).abs() < 1e-12);
    }

    #[test]
    fn sidak_keeps_the_overall_level() {
        let per_test = sidak_significance(0.01, 10);
        assert!((1.0 - libm::pow(1.0 - per_test, 10.0) - 0.01).abs() < 1e-12);
    }

    #[test]
    fn uniform_pdfs_integrate_to_one() {
        let sphere = pdf_integral(&|d| UniformSphere.pdf(d), Vec3::Z, 64, 6);
        assert!((sphere - 1.0).abs() < 1e-6, "{sphere}");
        let hemisphere = UniformHemisphere::new(Vec3::new(0.3, 0.4, -0.866).normalize());
        let total = pdf_integral(&|d| hemisphere.pdf(d), Vec3::Y, 64, 8);
        assert!((total - 1.0).abs() < 1e-3, "{total}");
    }

    #[test]
    fn correct_samplers_pass() {
        let settings = ChiSquareSettings { samples: 200_000, ..Default::default() };
        let report = chi_square_test(&UniformHemisphere::new(Vec3::Y), Vec3::Y, &settings);
        assert!(report.passes(0.001), "{report:?}");
        let report = chi_square_test(&UniformSphere, Vec3::new(1.0, 1.0, 0.0).normalize(), &settings);
        assert!(report.passes(0.001), "{report:?}");
    }

    /// Claims to be uniform but draws cos θ ∝ u² (too many grazing directions).
    struct SkewedHemisphere;

    impl DirectionalDistribution for SkewedHemisphere {
        fn sample(&self, u: Vec2) -> DirectionSample {
            let mut s = UniformHemisphere::new(Vec3::Z).sample(Vec2::new(u.x * u.x, u.y));
            s.pdf = 0.5 / core::f32::consts::PI;
            s
        }
        fn pdf(&self, direction: Vec3) -> f32 {
            UniformHemisphere::new(Vec3::Z).pdf(direction)
        }
    }

    /// Samples the whole sphere while its pdf claims only the upper hemisphere.
    struct LeakyHemisphere;

    impl DirectionalDistribution for LeakyHemisphere {
        fn sample(&self, u: Vec2) -> DirectionSample {
            let mut s = UniformSphere.sample(u);
            s.pdf = 0.5 / core::f32::consts::PI;
            s
        }
        fn pdf(&self, direction: Vec3) -> f32 {
            UniformHemisphere::new(Vec3::Z).pdf(direction)
        }
    }

    #[test]
    fn wrong_samplers_fail() {
        let settings = ChiSquareSettings { samples: 200_000, ..Default::default() };
        let report = chi_square_test(&SkewedHemisphere, Vec3::Z, &settings);
        assert!(!report.passes(0.001) && report.p_value < 1e-10, "{report:?}");
        let report = chi_square_test(&LeakyHemisphere, Vec3::Z, &settings);
        assert!(!report.passes(0.001), "{report:?}");
        assert!(report.inconsistent_samples > 0 || report.samples_in_zero_cells > 0);
    }
}
