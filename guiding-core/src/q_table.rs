//! The table machinery the hemisphere grid and the irradiance volume share: one step of
//! Eq. (1)'s update of a table entry, and the estimators of Eq. (1)'s integral over one
//! region's row of piecewise-constant Q. Each structure keeps its own layout (a probe's
//! hemisphere in its local frame, a leaf's sphere in world axes) and answers for it
//! through [`TableRow`].

use core::sync::atomic::AtomicU32;

use glam::{Vec2, Vec3};

use crate::atomic_f32;
use crate::scattering::ScatteringFunction;
use crate::update_rule::{blend, IntegralEstimator, UpdateRule};

/// One table entry and the counters its update moves.
pub(crate) struct EntrySlots<'a> {
    /// The entry's Q (f32 bits).
    pub(crate) q: &'a AtomicU32,
    /// The entry's update count.
    pub(crate) visits: &'a AtomicU32,
    /// The entry's Σ of importance weights (f32 bits): the simple average's denominator.
    pub(crate) weights: &'a AtomicU32,
    /// The update count of the entry's region (probe or leaf).
    pub(crate) region_visits: &'a AtomicU32,
}

/// Blends an accepted `target` into the entry with the rule's α for an update weighing
/// `weight` (1 unweighted), counting the visit in the entry and its region. Returns Q
/// before and after.
#[inline]
pub(crate) fn learn_entry(
    slots: EntrySlots<'_>,
    target: f32,
    weight: f32,
    rule: &UpdateRule,
    epoch: u32,
    floor: f32,
) -> (f32, f32) {
    let entry_visits = atomic_f32::increment_saturating(slots.visits);
    let region_visits = atomic_f32::increment_saturating(slots.region_visits);
    let alpha = rule.learning_rate.weighted_alpha((entry_visits, slots.weights), region_visits, epoch, weight);
    atomic_f32::update(slots.q, |q| blend(q, target, alpha, floor))
}

/// One region's row of a table, as the integral estimators see it.
pub(crate) trait TableRow {
    /// The row's Q, one per entry (f32 bits).
    fn q(&self) -> &[AtomicU32];
    /// The solid angle every entry covers (steradians).
    fn entry_solid_angle(&self) -> f64;
    /// The entry holding world direction `wi`, if the row covers it.
    fn entry_of(&self, wi: Vec3) -> Option<usize>;
    /// Entry `k`'s centre direction (world).
    fn center(&self, k: usize) -> Vec3;
    /// cos θ of entry `k`'s centre about the region's normal, 0 below it.
    fn center_cos(&self, k: usize) -> f32;
    /// A direction inside entry `k` placed by `u` (world).
    fn direction_in_entry(&self, k: usize, u: Vec2) -> Vec3;
    /// ∫ Q cos θ dω / π over the normal's hemisphere times `albedo`: a Lambertian
    /// BSDF's integral in closed form, from what the structure keeps for it.
    fn lambertian_integral(&self, albedo: f32) -> f64;
}

/// Eq. (1)'s integral ∫ Q(ωi) fs(ωi, `wo`) cos θi dωi over `row` by `integral`:
/// - `BsdfWeightedSum`: a Lambertian BSDF's closed form, otherwise Σ_k Q_k·fs·cos·ΔΩ
///   at entry centres;
/// - `BsdfSampled` and `PathContinuation` (where the tracer asks for an estimate at
///   all): the same for Lambertian BSDFs, one BSDF-drawn direction otherwise;
/// - `StratifiedPatches`: the sum at one direction per entry placed by `u`;
/// - `MaxEntry`: π · max_k of the centre terms.
///
/// Clamped to f32's range.
#[inline]
pub(crate) fn estimate_row_integral<S: ScatteringFunction + ?Sized>(
    integral: IntegralEstimator,
    row: &impl TableRow,
    bsdf: &S,
    wo: Vec3,
    u: Vec2,
) -> f32 {
    let lambertian = bsdf.lambertian_albedo();
    let at_center = |k: usize| match lambertian {
        Some(albedo) => albedo * core::f32::consts::FRAC_1_PI * row.center_cos(k),
        None => bsdf.eval_cos(row.center(k), wo),
    };
    // Q of every entry, read only by the estimators that need the whole row.
    let terms = || row.q().iter().map(|q| atomic_f32::load(q) as f64).enumerate();
    let estimate = match integral {
        IntegralEstimator::BsdfSampled | IntegralEstimator::PathContinuation
            if lambertian.is_none() && bsdf.can_sample() =>
        {
            let Some(sample) = bsdf.sample_cos(wo, u) else { return 0.0 };
            let q = row.entry_of(sample.wi).map_or(0.0, |k| atomic_f32::load(&row.q()[k]));
            q as f64 * sample.weight as f64
        }
        IntegralEstimator::BsdfWeightedSum | IntegralEstimator::BsdfSampled | IntegralEstimator::PathContinuation => {
            match lambertian {
                Some(albedo) => row.lambertian_integral(albedo),
                None => row.entry_solid_angle() * terms().map(|(k, q)| q * at_center(k) as f64).sum::<f64>(),
            }
        }
        IntegralEstimator::StratifiedPatches => {
            let jittered = |k: usize| bsdf.eval_cos(row.direction_in_entry(k, u), wo) as f64;
            row.entry_solid_angle() * terms().map(|(k, q)| q * jittered(k)).sum::<f64>()
        }
        IntegralEstimator::MaxEntry => {
            core::f64::consts::PI * terms().map(|(k, q)| q * at_center(k) as f64).fold(0.0, f64::max)
        }
    };
    estimate.min(f32::MAX as f64) as f32
}

/// The check of bug 2 of the guiding issue for a table structure: `learned(p_guide,
/// weighted)` is the Q one entry learned through a mixture that drew its directions
/// from the structure with probability `p_guide` (cosine-weighted otherwise), passing
/// each direction's pdf (`weighted`) or none. Weighted, it must be the entry's mean
/// `exact` within 6 % at p_guide 0.1 and 0.9; unweighted at 0.1, below 0.9 × it (so the
/// field the caller chose can tell the two apart).
#[cfg(test)]
pub(crate) fn assert_learning_ignores_the_density(learned: impl Fn(f32, bool) -> f64, exact: f64) {
    for p_guide in [0.1, 0.9] {
        let q = learned(p_guide, true);
        assert!((q / exact - 1.0).abs() < 0.06, "p_guide {p_guide}: Q {q}, exact mean {exact}");
    }
    let unweighted = learned(0.1, false);
    assert!(unweighted / exact < 0.9, "unweighted Q {unweighted}, exact mean {exact}");
}
