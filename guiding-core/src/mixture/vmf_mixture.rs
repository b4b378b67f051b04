//! [`VmfMixture`]: a weighted sum of up to [`MAX_LOBES`] von Mises–Fisher lobes, with an
//! exact sampler and pdf, fitted online by weighted stepwise EM.

use glam::{Vec2, Vec3};

use crate::distribution::{DirectionSample, DirectionalDistribution};

use super::vmf::{VmfLobe, MAX_CONCENTRATION};

/// The most lobes a mixture holds (fixed-size storage: nothing allocates).
pub const MAX_LOBES: usize = 8;

/// Lobes whose weight falls below this share are reset by the fit onto the sample
/// that most needs a lobe (weights → 0 guard).
pub const MIN_LOBE_WEIGHT: f32 = 1e-4;

/// Largest mean resultant length r̄ the M-step uses: κ = r̄(3 − r̄²)/(1 − r̄²) then stays
/// below [`MAX_CONCENTRATION`] (κ → ∞ guard).
const MAX_MEAN_RESULTANT: f32 = 0.9999;

/// A mixture Σ_k w_k·vMF(μ_k, κ_k) over the sphere, with the sufficient statistics of its
/// stepwise-EM fit: per lobe, the running average of the responsibility-weighted sample
/// weight (S0) and of the responsibility-weighted sample direction times weight (S1).
///
/// Samples (ω, v) come with a non-negative weight v = target / density the direction was
/// drawn with (so directions drawn often do not count more). Each one moves the
/// statistics towards its own by a step η: η = 1/(1+n) averages all samples alike (the
/// seed's simple averaging), a constant η forgets old ones exponentially. The M-step then
/// sets w_k = S0_k/ΣS0, μ_k = S1_k/|S1_k| and κ_k from r̄_k = |S1_k|/S0_k by Banerjee's
/// approximation κ = r̄(3 − r̄²)/(1 − r̄²).
///
/// ```
/// use guiding_core::mixture::VmfMixture;
/// use guiding_core::{DirectionalDistribution, Pcg32};
/// use glam::Vec3;
/// // Light arrives from around +x: fit 4 lobes to samples weighted by it.
/// let mut mixture = VmfMixture::uniform(4);
/// let mut rng = Pcg32::new(1, 1);
/// for n in 0..20_000u32 {
///     let s = mixture.sample(rng.next_vec2());
///     let light = (s.direction.x - 0.8).max(0.0);
///     mixture.observe(s.direction, light / s.pdf, 1.0 / (1.0 + n as f32));
/// }
/// mixture.refit();
/// assert!(mixture.pdf(Vec3::X) > 20.0 * mixture.pdf(-Vec3::X));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VmfMixture {
    count: usize,
    weights: [f32; MAX_LOBES],
    lobes: [VmfLobe; MAX_LOBES],
    /// Running averages of Σ r·v (S0) and Σ r·v·ω (S1) per lobe.
    weight_statistics: [f32; MAX_LOBES],
    direction_statistics: [Vec3; MAX_LOBES],
    /// Samples observed since creation.
    observations: u32,
}

/// Directions spread over the sphere for the initial lobes (a cube's corners and faces).
const INITIAL_MEANS: [Vec3; MAX_LOBES] = [
    Vec3::new(1.0, 1.0, 1.0),
    Vec3::new(-1.0, -1.0, 1.0),
    Vec3::new(-1.0, 1.0, -1.0),
    Vec3::new(1.0, -1.0, -1.0),
    Vec3::new(-1.0, 1.0, 1.0),
    Vec3::new(1.0, -1.0, 1.0),
    Vec3::new(1.0, 1.0, -1.0),
    Vec3::new(-1.0, -1.0, -1.0),
];

/// Concentration of the initial lobes: broad enough that together they cover the sphere.
const INITIAL_CONCENTRATION: f32 = 2.0;

impl VmfMixture {
    /// `lobes` (clamped to 1..=[`MAX_LOBES`]) equal, broad lobes spread over the sphere.
    pub fn uniform(lobes: usize) -> Self {
        let count = lobes.clamp(1, MAX_LOBES);
        let lobes = core::array::from_fn(|k| VmfLobe::new(INITIAL_MEANS[k], INITIAL_CONCENTRATION));
        let weights = core::array::from_fn(|k| if k < count { 1.0 / count as f32 } else { 0.0 });
        Self {
            count,
            weights,
            lobes,
            weight_statistics: [0.0; MAX_LOBES],
            direction_statistics: [Vec3::ZERO; MAX_LOBES],
            observations: 0,
        }
    }

    /// Number of lobes.
    pub fn lobe_count(&self) -> usize {
        self.count
    }

    /// Lobe `k` and its weight.
    pub fn lobe(&self, k: usize) -> (VmfLobe, f32) {
        (self.lobes[k], self.weights[k])
    }

    /// Samples observed since creation.
    pub fn observations(&self) -> u32 {
        self.observations
    }

    /// E-step for one sample: moves each lobe's statistics towards the sample's by step
    /// `step` in (0, 1] (1/(1+n) for simple averaging, a constant for exponential).
    /// `direction` must be unit; `weight` (target / sampling density) must be finite and
    /// ≥ 0. Returns false, changing nothing, for anything else.
    pub fn observe(&mut self, direction: Vec3, weight: f32, step: f32) -> bool {
        let valid_direction = direction.is_finite() && (direction.length_squared() - 1.0).abs() < 1e-3;
        if !(valid_direction && weight.is_finite() && weight >= 0.0 && step > 0.0 && step <= 1.0) {
            return false;
        }
        let responsibility = self.responsibilities(direction);
        let s0: [f32; MAX_LOBES] = core::array::from_fn(|k| responsibility[k] * weight);
        let s1: [Vec3; MAX_LOBES] = core::array::from_fn(|k| s0[k] * direction);
        self.absorb(&s0, &s1, step);
        self.observations = self.observations.saturating_add(1);
        true
    }

    /// The E-step's responsibilities r_k = w_k f_k(ω) / Σ_j w_j f_j(ω) of unit
    /// `direction`; they sum to 1 over the lobes (a direction no lobe claims, all having
    /// underflowed, goes to the broadest) and are 0 past [`lobe_count`](Self::lobe_count).
    pub fn responsibilities(&self, direction: Vec3) -> [f32; MAX_LOBES] {
        let mut responsibility: [f32; MAX_LOBES] =
            core::array::from_fn(|k| if k < self.count { self.weights[k] * self.lobes[k].pdf(direction) } else { 0.0 });
        let total: f32 = responsibility.iter().sum();
        if total > 0.0 && total.is_finite() {
            responsibility.iter_mut().for_each(|r| *r /= total);
        } else {
            responsibility = [0.0; MAX_LOBES];
            responsibility[self.broadest()] = 1.0;
        }
        responsibility
    }

    /// Moves the statistics towards a batch's averages by step `step` in (0, 1]:
    /// `s0[k]` = mean of r_k·v and `s1[k]` = mean of r_k·v·ω over the batch (a batch of
    /// one is [`observe`](Self::observe)). Evaluated in f64 and clamped to f32's range, so
    /// extreme weights saturate instead of overflowing. Anything not finite is ignored.
    pub fn absorb(&mut self, s0: &[f32; MAX_LOBES], s1: &[Vec3; MAX_LOBES], step: f32) {
        let finite = s0[..self.count].iter().all(|v| v.is_finite() && *v >= 0.0)
            && s1[..self.count].iter().all(|v| v.is_finite());
        if !(finite && step > 0.0 && step <= 1.0) {
            return;
        }
        let step = step as f64;
        let mix = |old: f32, new: f32| {
            let value = (1.0 - step) * old as f64 + step * new as f64;
            value.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
        };
        for k in 0..self.count {
            self.weight_statistics[k] = mix(self.weight_statistics[k], s0[k]);
            let (old, new) = (self.direction_statistics[k], s1[k]);
            self.direction_statistics[k] = Vec3::new(mix(old.x, new.x), mix(old.y, new.y), mix(old.z, new.z));
        }
    }

    /// Takes in `other`'s statistics as if its samples had been observed here: each of
    /// its lobes is paired with the nearest lobe of this mixture by mean direction
    /// (heaviest first, each lobe once), the paired statistics are averaged by the two
    /// mixtures' observation counts, and the mixture is refitted. Both must have the same
    /// number of lobes (else nothing changes and `false` is returned).
    ///
    /// An approximation: each mixture weighed its samples by responsibilities under its
    /// own lobes, so two lobes paired here may have split their samples differently; a
    /// pair that followed different lights averages into one broader lobe, which keeps
    /// both directions' density above zero.
    pub fn merge(&mut self, other: &VmfMixture) -> bool {
        if self.count != other.count {
            return false;
        }
        let (mine, theirs) = (self.observations as f64, other.observations as f64);
        if theirs == 0.0 {
            return true;
        }
        let mut order: [usize; MAX_LOBES] = core::array::from_fn(|k| k);
        order[..other.count].sort_by(|&a, &b| other.weight_statistics[b].total_cmp(&other.weight_statistics[a]));
        let (mut taken, mut s0, mut s1) = ([false; MAX_LOBES], [0.0f32; MAX_LOBES], [Vec3::ZERO; MAX_LOBES]);
        for &j in &order[..other.count] {
            let toward = other.lobes[j].mean();
            let nearest = (0..self.count)
                .filter(|&k| !taken[k])
                .max_by(|&a, &b| self.lobes[a].mean().dot(toward).total_cmp(&self.lobes[b].mean().dot(toward)));
            let Some(k) = nearest else { break };
            taken[k] = true;
            s0[k] = other.weight_statistics[j];
            s1[k] = other.direction_statistics[j];
        }
        self.absorb(&s0, &s1, (theirs / (mine + theirs)) as f32);
        self.refit();
        self.observations = self.observations.saturating_add(other.observations);
        true
    }

    /// The running average of the sample weights (Σ_k S0_k): with weights target/density,
    /// an estimate of ∫ target dω over the sphere (radiance × steradian).
    pub fn total_weight(&self) -> f32 {
        let total: f64 = self.weight_statistics[..self.count].iter().map(|&s| s as f64).sum();
        total.min(f32::MAX as f64) as f32
    }

    /// Each lobe's share of [`total_weight`](Self::total_weight): S0_k.
    pub fn lobe_weight_statistics(&self) -> &[f32] {
        &self.weight_statistics[..self.count]
    }

    /// A mixture of the given lobes and weights (at most [`MAX_LOBES`]; weights are
    /// normalised, a non-positive or non-finite sum gives equal weights) whose statistics
    /// describe it as if fitted to samples of total weight `total_weight` (≥ 0): S0_k =
    /// total·w_k and S1_k = S0_k·A(κ_k)·μ_k, A(κ) = coth κ − 1/κ the mean resultant
    /// length of a vMF lobe, so a refit keeps it close.
    pub fn from_lobes(lobes: &[(VmfLobe, f32)], total_weight: f32) -> Self {
        let count = lobes.len().clamp(1, MAX_LOBES);
        let mut mixture = Self::uniform(count);
        let clean = |w: f32| if w.is_finite() && w > 0.0 { w } else { 0.0 };
        let sum: f32 = lobes.iter().take(count).map(|&(_, w)| clean(w)).sum();
        let total = if total_weight.is_finite() && total_weight > 0.0 { total_weight } else { 0.0 };
        for (k, &(lobe, w)) in lobes.iter().take(count).enumerate() {
            let weight = if sum > 0.0 && sum.is_finite() { clean(w) / sum } else { 1.0 / count as f32 };
            mixture.lobes[k] = lobe;
            mixture.weights[k] = weight;
            mixture.weight_statistics[k] = total * weight;
            mixture.direction_statistics[k] =
                total * weight * mean_resultant_length(lobe.concentration()) * lobe.mean();
        }
        mixture
    }

    /// The raw parts, for serialization: lobes, weights, S0, S1 and the observation count.
    pub(crate) fn parts(&self) -> (&[VmfLobe], &[f32], &[f32], &[Vec3], u32) {
        let n = self.count;
        (
            &self.lobes[..n],
            &self.weights[..n],
            &self.weight_statistics[..n],
            &self.direction_statistics[..n],
            self.observations,
        )
    }

    /// A mixture from raw parts (as [`parts`](Self::parts) gives them; the caller has
    /// checked every value is finite, weights ≥ 0 summing to 1, S0 ≥ 0).
    pub(crate) fn from_parts(lobes: &[VmfLobe], weights: &[f32], s0: &[f32], s1: &[Vec3], observations: u32) -> Self {
        let count = lobes.len().clamp(1, MAX_LOBES);
        let mut mixture = Self::uniform(count);
        mixture.lobes[..count].copy_from_slice(&lobes[..count]);
        mixture.weights[..count].copy_from_slice(&weights[..count]);
        mixture.weight_statistics[..count].copy_from_slice(&s0[..count]);
        mixture.direction_statistics[..count].copy_from_slice(&s1[..count]);
        mixture.observations = observations;
        mixture
    }

    /// Counts `count` more observed samples (those a batch passed to
    /// [`absorb`](Self::absorb) carried).
    pub fn add_observations(&mut self, count: u32) {
        self.observations = self.observations.saturating_add(count);
    }

    /// M-step: sets weights, means and concentrations from the statistics. Lobes that
    /// gathered no weight keep their shape at a small weight floor (so every direction
    /// keeps a positive density); a mixture that saw no weight at all is left unchanged.
    pub fn refit(&mut self) {
        let total: f32 = self.weight_statistics[..self.count].iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return;
        }
        let count = self.count;
        let statistics = self.weight_statistics.iter().zip(&self.direction_statistics);
        let lobes = self.weights.iter_mut().zip(self.lobes.iter_mut());
        for ((&s0, &s1), (weight, lobe)) in statistics.zip(lobes).take(count) {
            *weight = (s0 / total).max(MIN_LOBE_WEIGHT);
            let length = s1.length();
            if s0 > 0.0 && length > 0.0 && length.is_finite() {
                let mean_resultant = (length / s0).min(MAX_MEAN_RESULTANT);
                let r2 = mean_resultant * mean_resultant;
                let kappa = mean_resultant * (3.0 - r2) / (1.0 - r2);
                *lobe = VmfLobe::new(s1 / length, kappa.min(MAX_CONCENTRATION));
            }
        }
        let sum: f32 = self.weights[..count].iter().sum();
        self.weights[..count].iter_mut().for_each(|w| *w /= sum);
    }

    /// The lobe with the smallest concentration.
    fn broadest(&self) -> usize {
        (0..self.count)
            .min_by(|&a, &b| self.lobes[a].concentration().total_cmp(&self.lobes[b].concentration()))
            .unwrap_or(0)
    }
}

/// A(κ) = coth κ − 1/κ, the mean resultant length E[μ·ω] of a vMF lobe (0 at κ = 0).
fn mean_resultant_length(kappa: f32) -> f32 {
    let kappa = kappa as f64;
    if kappa < 1e-3 {
        return (kappa / 3.0) as f32;
    }
    // coth κ = (1 + e^{−2κ}) / (1 − e^{−2κ}), finite for every κ > 0.
    let e = libm::exp(-2.0 * kappa);
    ((1.0 + e) / (1.0 - e) - 1.0 / kappa) as f32
}

impl DirectionalDistribution for VmfMixture {
    /// Picks a lobe by weight from `u.x`, rescales the rest of `u.x` and samples the lobe.
    fn sample(&self, u: Vec2) -> DirectionSample {
        let mut cumulative = 0.0f32;
        let mut chosen = self.count - 1;
        let mut low = 0.0f32;
        for k in 0..self.count {
            let next = cumulative + self.weights[k];
            if u.x < next || k == self.count - 1 {
                chosen = k;
                low = cumulative;
                break;
            }
            cumulative = next;
        }
        let width = self.weights[chosen];
        let rest = if width > 0.0 { ((u.x - low) / width).clamp(0.0, 1.0 - f32::EPSILON / 2.0) } else { 0.5 };
        let direction = self.lobes[chosen].sample(Vec2::new(rest, u.y));
        DirectionSample { direction, pdf: self.pdf(direction) }
    }

    /// Σ_k w_k·pdf_k(direction).
    fn pdf(&self, direction: Vec3) -> f32 {
        (0..self.count).map(|k| self.weights[k] * self.lobes[k].pdf(direction)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;
    use crate::validation::{chi_square_test, pdf_integral, ChiSquareSettings};

    /// Fits `mixture` to light ∝ `radiance(ω)` by sampling itself, as a renderer would.
    fn fit(mixture: &mut VmfMixture, radiance: impl Fn(Vec3) -> f32, samples: u32, rounds: u32, seed: u64) {
        let mut rng = Pcg32::new(seed, 7);
        let mut n = 0u32;
        for _ in 0..rounds {
            for _ in 0..samples {
                let s = mixture.sample(rng.next_vec2());
                mixture.observe(s.direction, radiance(s.direction) / s.pdf, 1.0 / (1.0 + n as f32));
                n += 1;
            }
            mixture.refit();
        }
    }

    #[test]
    fn a_fitted_mixture_matches_its_sampler_and_integrates_to_one() {
        let mut mixture = VmfMixture::uniform(6);
        let sun = Vec3::new(0.2, 0.9, -0.3).normalize();
        let sky = |d: Vec3| 0.2 * d.y.max(0.0) + 50.0 * (d.dot(sun) - 0.98).max(0.0);
        fit(&mut mixture, sky, 4000, 8, 3);
        // Five levels (a quarter of six's evaluations) keep ∫ within 2e-3 of one.
        let total = pdf_integral(&|d| mixture.pdf(d), Vec3::Y, 32, 5);
        assert!((total - 1.0).abs() < 2e-3, "∫ = {total}");
        let settings = ChiSquareSettings { theta_bins: 24, phi_bins: 48, samples: 2_000_000, ..Default::default() };
        let report = chi_square_test(&mixture, Vec3::Y, &settings);
        assert!(report.passes(0.01), "{report:?}");
        // The fit found the sun: its direction is far more likely than the ground's.
        assert!(mixture.pdf(sun) > 50.0 * mixture.pdf(-Vec3::Y), "{} vs {}", mixture.pdf(sun), mixture.pdf(-Vec3::Y));
    }

    #[test]
    fn a_deliberately_wrong_pdf_fails_chi_square() {
        struct Wrong(VmfMixture);
        impl DirectionalDistribution for Wrong {
            fn sample(&self, u: Vec2) -> DirectionSample {
                self.0.sample(u)
            }
            fn pdf(&self, d: Vec3) -> f32 {
                self.0.pdf(d) * if d.z > 0.0 { 1.1 } else { 0.9 }
            }
        }
        let mut mixture = VmfMixture::uniform(3);
        fit(&mut mixture, |d| (d.x + 0.5).max(0.0), 3000, 4, 5);
        let settings = ChiSquareSettings { theta_bins: 24, phi_bins: 48, samples: 500_000, ..Default::default() };
        assert!(!chi_square_test(&Wrong(mixture), Vec3::Y, &settings).passes(0.01));
    }

    #[test]
    fn one_lobe_recovers_a_known_vmf() {
        // Samples drawn from vMF(μ, 30) with weight 1: the M-step's κ is Banerjee's
        // estimate, within a few percent of 30 for this many samples.
        let truth = VmfLobe::new(Vec3::new(-0.4, 0.1, 0.9), 30.0);
        let mut mixture = VmfMixture::uniform(1);
        let mut rng = Pcg32::new(8, 8);
        for n in 0..100_000u32 {
            mixture.observe(truth.sample(rng.next_vec2()), 1.0, 1.0 / (1.0 + n as f32));
        }
        mixture.refit();
        let (lobe, weight) = mixture.lobe(0);
        assert_eq!(weight, 1.0);
        assert!(lobe.mean().dot(truth.mean()) > 0.9995, "{:?}", lobe.mean());
        assert!((lobe.concentration() - 30.0).abs() < 1.5, "κ = {}", lobe.concentration());
    }

    #[test]
    fn bad_samples_change_nothing() {
        let mut mixture = VmfMixture::uniform(4);
        let before = mixture;
        for (d, w, step) in [
            (Vec3::NAN, 1.0, 0.5),
            (Vec3::new(2.0, 0.0, 0.0), 1.0, 0.5),
            (Vec3::Y, f32::NAN, 0.5),
            (Vec3::Y, f32::INFINITY, 0.5),
            (Vec3::Y, -1.0, 0.5),
            (Vec3::Y, 1.0, 0.0),
            (Vec3::Y, 1.0, 1.5),
            (Vec3::Y, 1.0, f32::NAN),
        ] {
            assert!(!mixture.observe(d, w, step), "{d} {w} {step}");
        }
        mixture.refit();
        assert_eq!(mixture, before);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Whatever the stream (weights 0…1e30, one direction repeated until κ would be
        /// infinite, steps from 1e-6 to 1), the mixture stays a finite, positive density
        /// and its sampler returns unit directions.
        #[test]
        fn any_stream_keeps_the_mixture_finite_and_positive(
            lobes in 1usize..=MAX_LOBES,
            stream in proptest::collection::vec((-1.0f32..1.0, 0.0f32..1.0, proptest::prop_oneof![
                proptest::prelude::Just(0.0f32), 0.0f32..1.0, 1e20f32..1e30], 1e-6f32..=1.0), 1..300),
            repeat in proptest::bool::ANY,
        ) {
            let mut mixture = VmfMixture::uniform(lobes);
            for (i, &(z, phi, weight, step)) in stream.iter().enumerate() {
                let (z, phi) = if repeat { (0.3, 0.2) } else { (z, phi) };
                let r = (1.0 - z * z).max(0.0).sqrt();
                let angle = 2.0 * core::f32::consts::PI * phi;
                let d = Vec3::new(r * libm::cosf(angle), z, r * libm::sinf(angle)).normalize();
                mixture.observe(d, weight, step);
                if i % 16 == 15 {
                    mixture.refit();
                }
            }
            mixture.refit();
            let total: f32 = (0..mixture.lobe_count()).map(|k| mixture.lobe(k).1).sum();
            proptest::prop_assert!((total - 1.0).abs() < 1e-4, "weights sum to {}", total);
            let mut rng = Pcg32::new(1, 2);
            for _ in 0..64 {
                let s = mixture.sample(rng.next_vec2());
                proptest::prop_assert!(s.direction.is_finite() && (s.direction.length() - 1.0).abs() < 1e-4);
                proptest::prop_assert!(s.pdf.is_finite() && s.pdf > 0.0, "pdf {}", s.pdf);
                let anywhere = mixture.pdf(-s.direction);
                proptest::prop_assert!(anywhere.is_finite() && anywhere >= 0.0);
            }
        }
    }
}
