//! How a Q value moves towards a new target: Eq. (1) and (2) and their variants.
//!
//! ```text
//! Q'(x,ω) = (1-α)·Q(x,ω) + α·target,   target = Le(y,-ω) + ∫ Q(y,ωi) fs(ωi,y,-ω) cos θi dωi
//! ```
//!
//! [`LearningRate`] chooses α; [`IntegralEstimator`] chooses how a guide estimates the
//! integral part of the target at the next vertex y ([`Guide::estimate_integral`]).
//!
//! [`Guide::estimate_integral`]: crate::Guide::estimate_integral

use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

use crate::atomic_f32;
use crate::error::Error;

/// The learning rate α of Eq. (1).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum LearningRate {
    /// A constant α in [0, 1]: Q is the exponential moving average of its targets, which
    /// keeps adapting as the targets change. α = 0 never changes Q; α = 1 replaces it.
    Exponential {
        /// The constant α, in [0, 1].
        alpha: f32,
    },
    /// α = 1/(1 + visits(x, ω)), Eq. (2), counted per entry (patch): Q is the simple
    /// (arithmetic) average of every target the entry accepted; the initial value is
    /// replaced by the first.
    SimpleAverage,
    /// α = 1/(1 + visits(x)), counted per region (probe): all of a region's entries
    /// slow down together.
    RegionVisits,
    /// A global schedule α = (1 + epoch)^(-exponent), where the epoch counts calls to
    /// [`Guide::rebuild_sampling`](crate::Guide::rebuild_sampling) (passes). An exponent in
    /// (½, 1] satisfies the Robbins–Monro conditions; 0 gives α = 1.
    Global {
        /// Decay exponent, in [0, 4].
        exponent: f32,
    },
}

impl LearningRate {
    /// α for an entry visited `entry_visits` times in a region visited `region_visits`
    /// times, during learning epoch `epoch` (all counts before this update).
    pub fn alpha(&self, entry_visits: u32, region_visits: u32, epoch: u32) -> f32 {
        match *self {
            LearningRate::Exponential { alpha } => alpha,
            LearningRate::SimpleAverage => (1.0 / (1.0 + entry_visits as f64)) as f32,
            LearningRate::RegionVisits => (1.0 / (1.0 + region_visits as f64)) as f32,
            LearningRate::Global { exponent } => libm::pow(1.0 + epoch as f64, -(exponent as f64)) as f32,
        }
    }

    /// α for an update that weighs `weight` (an [`importance_weight`]; 1 unweighted),
    /// given the entry's visit count before it and its Σ of weights, to which this adds
    /// `weight`. The simple average steps by w / (W + w), the weighted mean of every
    /// target so far; the other rates by [`weighted_step`] of their α.
    #[cfg_attr(not(any(feature = "hemisphere", feature = "volume")), allow(dead_code))]
    pub(crate) fn weighted_alpha(&self, entry: (u32, &AtomicU32), region_visits: u32, epoch: u32, weight: f32) -> f32 {
        let (entry_visits, weights) = entry;
        let (before, _) = atomic_f32::update(weights, |w| (w + weight).min(f32::MAX));
        match *self {
            LearningRate::SimpleAverage if weight > 0.0 => (weight as f64 / (before as f64 + weight as f64)) as f32,
            LearningRate::SimpleAverage => 0.0,
            _ => weighted_step(self.alpha(entry_visits, region_visits, epoch), weight),
        }
    }

    fn validate(&self) -> Result<(), Error> {
        match *self {
            LearningRate::Exponential { alpha } if !(0.0..=1.0).contains(&alpha) => Err(Error::InvalidSetting {
                name: "learning_rate.alpha",
                value: alpha as f64,
                requirement: "in [0, 1]",
            }),
            LearningRate::Global { exponent } if !(0.0..=4.0).contains(&exponent) => Err(Error::InvalidSetting {
                name: "learning_rate.exponent",
                value: exponent as f64,
                requirement: "in [0, 4]",
            }),
            _ => Ok(()),
        }
    }
}

/// How the integral `∫ Q(y,ωi) fs cos θi dωi` at the next vertex is estimated from a
/// region's piecewise-constant Q (N entries, each covering a solid angle ΔΩ).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum IntegralEstimator {
    /// Σ Q_j · w_j with w_j = ∫ over entry j of fs cos dω: exact weights when the BSDF is
    /// Lambertian (precomputed cosine integrals), otherwise fs·cos at the entry's centre
    /// times ΔΩ. Deterministic, no noise, O(N) multiply-adds.
    BsdfWeightedSum,
    /// Σ Q_j · fs(ω_j)·cos θ_j · ΔΩ with one direction ω_j jittered inside each entry (the
    /// same jitter for all entries, from the caller's uniform numbers): unbiased for the
    /// piecewise-constant Q, at the cost of one BSDF evaluation per entry.
    StratifiedPatches,
    /// π · max_j Q_j · fs(ω_j)·cos θ_j at entry centres: Q-learning's "best action". It
    /// equals the integral for a constant Q and a Lambertian BSDF, and overestimates
    /// otherwise; Dahm & Keller found it worse, it is kept for comparison.
    MaxEntry,
    /// For a Lambertian BSDF the exact weighted sum (as [`BsdfWeightedSum`](Self::BsdfWeightedSum));
    /// for any other that can sample itself ([`ScatteringFunction::sample_cos`]), one
    /// direction ω drawn from it: Q(ω)·fs·cos θ/pdf, unbiased for the piecewise-constant Q
    /// at O(1) instead of N BSDF evaluations (glossy surfaces); the weighted sum for
    /// BSDFs that cannot sample.
    ///
    /// [`ScatteringFunction::sample_cos`]: crate::ScatteringFunction::sample_cos
    BsdfSampled,
    /// No estimate at the next vertex: the path's own continuation stands for the
    /// integral (the radiance the path actually brought back through the direction,
    /// scaled by the next vertex's fs·cos/pdf and Russian roulette), which is what
    /// Practical Path Guiding records. Needs no lookup; a one-sample estimate whose noise
    /// the averaging removes. Guides asked for an estimate under this rule answer with
    /// [`BsdfSampled`](Self::BsdfSampled)'s.
    PathContinuation,
}

/// The complete update rule: learning rate and integral estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpdateRule {
    /// How α is chosen.
    pub learning_rate: LearningRate,
    /// How the integral of Eq. (1) is estimated at the next vertex.
    pub integral: IntegralEstimator,
}

impl Default for UpdateRule {
    fn default() -> Self {
        Self { learning_rate: LearningRate::SimpleAverage, integral: IntegralEstimator::BsdfSampled }
    }
}

impl UpdateRule {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), Error> {
        self.learning_rate.validate()
    }
}

/// How a target was taken by [`Guide::update`](crate::Guide::update).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum UpdateOutcome {
    /// The target was blended into Q.
    Accepted,
    /// The target was NaN or infinite: rejected, counted, not stored.
    RejectedNonFinite,
    /// The target was negative: rejected, counted, not stored.
    RejectedNegative,
    /// The direction lies outside the region's domain (below a probe's horizon, or not
    /// unit length and finite): nothing to update.
    OutsideDomain,
}

/// Checks a target before it may touch a table.
pub fn classify_target(target: f32) -> Result<f32, UpdateOutcome> {
    if !target.is_finite() {
        Err(UpdateOutcome::RejectedNonFinite)
    } else if target < 0.0 {
        Err(UpdateOutcome::RejectedNegative)
    } else {
        Ok(target)
    }
}

/// [`classify_target`], counting a rejected target in `negative` or `non_finite`: the
/// tables' rejection counters that their stats report.
#[cfg_attr(not(any(feature = "hemisphere", feature = "volume", feature = "mixture")), allow(dead_code))]
pub(crate) fn accept_target(
    target: f32,
    negative: &AtomicUsize,
    non_finite: &AtomicUsize,
) -> Result<f32, UpdateOutcome> {
    classify_target(target).inspect_err(|rejected| {
        let counter = if *rejected == UpdateOutcome::RejectedNegative { negative } else { non_finite };
        counter.fetch_add(1, Ordering::Relaxed);
    })
}

/// The weight of a direction drawn with density `pdf` (per steradian) in a table
/// entry's mean: `reference / pdf`, `reference` being the uniform density over the
/// table's domain (1/2π for a hemisphere, 1/4π for the sphere); `None` for a pdf that
/// is not finite and positive.
///
/// Weighted so, an entry's mean Σ w·t / Σ w estimates the mean of the target over the
/// entry's solid angle whatever mixture of BSDF and guide drew the directions; an
/// unweighted mean follows the drawing density inside the entry (bug 2 of the guiding
/// issue: Q then depended on p_guide and the BSDF).
pub fn importance_weight(reference: f32, pdf: f32) -> Option<f32> {
    (pdf.is_finite() && pdf > 0.0).then(|| (reference / pdf).min(f32::MAX))
}

/// A learning rate's step α for an update that weighs `weight`: αw / (1 + α(w − 1)),
/// which is α at w = 1, stays in [0, 1] for every w ≥ 0 and tends to αw for small α
/// (a weighted mean's step, as if the earlier updates had weighed 1 each).
pub fn weighted_step(alpha: f32, weight: f32) -> f32 {
    let (alpha, weight) = (alpha as f64, weight.max(0.0) as f64);
    let step = alpha * weight / (1.0 + alpha * (weight - 1.0));
    if step.is_finite() {
        step.clamp(0.0, 1.0) as f32
    } else {
        1.0
    }
}

#[cfg(any(feature = "hemisphere", feature = "mixture", feature = "tree", feature = "volume"))]
/// An atomic counter one guide's count can be added to from another's.
pub(crate) trait MergedCount {
    fn add_count(&self, other: &Self);
}

#[cfg(any(feature = "hemisphere", feature = "mixture", feature = "tree", feature = "volume"))]
impl MergedCount for AtomicU32 {
    fn add_count(&self, other: &Self) {
        self.fetch_add(other.load(Ordering::Relaxed), Ordering::Relaxed);
    }
}

#[cfg(any(feature = "hemisphere", feature = "mixture", feature = "tree", feature = "volume"))]
impl MergedCount for AtomicUsize {
    fn add_count(&self, other: &Self) {
        self.fetch_add(other.load(Ordering::Relaxed), Ordering::Relaxed);
    }
}

/// Adds another guide's counts of rejected targets (`[non-finite, negative]`) to this
/// one's, when the two merge.
#[cfg(any(feature = "hemisphere", feature = "mixture", feature = "tree", feature = "volume"))]
pub(crate) fn add_rejected_counts<C: MergedCount>(mine: [&C; 2], theirs: [&C; 2]) {
    for (count, other) in mine.into_iter().zip(theirs) {
        count.add_count(other);
    }
}

/// `(1-α)·q + α·target`, evaluated in f64 so that neither term can overflow or lose the
/// other, then clamped to `[floor, f32::MAX]`. With α = 0 the result is `q` exactly
/// (clamped), with α = 1 it is `target` exactly (clamped).
pub fn blend(q: f32, target: f32, alpha: f32, floor: f32) -> f32 {
    let alpha = alpha as f64;
    let mixed = if alpha <= 0.0 {
        q as f64
    } else if alpha >= 1.0 {
        target as f64
    } else {
        (1.0 - alpha) * q as f64 + alpha * target as f64
    };
    (mixed.min(f32::MAX as f64) as f32).max(floor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn learning_rates_follow_their_definitions() {
        assert_eq!(LearningRate::Exponential { alpha: 0.25 }.alpha(10, 10, 3), 0.25);
        assert_eq!(LearningRate::SimpleAverage.alpha(0, 50, 0), 1.0);
        assert_eq!(LearningRate::SimpleAverage.alpha(3, 50, 0), 0.25);
        assert_eq!(LearningRate::RegionVisits.alpha(0, 4, 0), 0.2);
        assert_eq!(LearningRate::Global { exponent: 1.0 }.alpha(9, 9, 3), 0.25);
        assert_eq!(LearningRate::Global { exponent: 0.0 }.alpha(9, 9, 3), 1.0);
        assert!(LearningRate::SimpleAverage.alpha(u32::MAX, 0, 0) > 0.0);
    }

    #[test]
    fn out_of_range_rates_are_rejected() {
        for alpha in [-0.1, 1.5, f32::NAN] {
            let rule = UpdateRule {
                learning_rate: LearningRate::Exponential { alpha },
                integral: IntegralEstimator::BsdfWeightedSum,
            };
            assert!(matches!(rule.validate(), Err(Error::InvalidSetting { name: "learning_rate.alpha", .. })));
        }
        let rule = UpdateRule { learning_rate: LearningRate::Global { exponent: f32::INFINITY }, ..Default::default() };
        assert!(rule.validate().is_err());
    }

    #[test]
    fn targets_are_classified() {
        assert_eq!(classify_target(f32::NAN), Err(UpdateOutcome::RejectedNonFinite));
        assert_eq!(classify_target(f32::NEG_INFINITY), Err(UpdateOutcome::RejectedNonFinite));
        assert_eq!(classify_target(-1e-30), Err(UpdateOutcome::RejectedNegative));
        assert_eq!(classify_target(-0.0), Ok(-0.0));
        assert_eq!(classify_target(1e30), Ok(1e30));
    }

    proptest! {
        #[test]
        fn blend_stays_finite_and_above_the_floor(
            q in prop_oneof![Just(f32::MIN_POSITIVE), Just(f32::MAX), 1e-30f32..1e30],
            target in prop_oneof![Just(0.0f32), Just(f32::MAX), 0.0f32..1e30, 1e-38f32..1e-20],
            alpha in 0.0f32..=1.0,
        ) {
            let floor = 1e-35;
            let next = blend(q, target, alpha, floor);
            prop_assert!(next.is_finite());
            prop_assert!(next >= floor);
            let (lo, hi) = if q < target { (q, target) } else { (target, q) };
            prop_assert!(next >= lo.max(floor) * (1.0 - 1e-6) && next <= hi.max(floor) * (1.0 + 1e-6));
        }

        #[test]
        fn alpha_zero_keeps_and_alpha_one_replaces(q in 1e-30f32..1e30, target in 0.0f32..1e30) {
            prop_assert_eq!(blend(q, target, 0.0, 1e-38), q);
            prop_assert_eq!(blend(q, target, 1.0, 1e-38), target.max(1e-38));
        }
    }
}
