//! The [`Guide`] trait: a spatio-directional table of Q values that learns and samples.

use alloc::vec::Vec;
use core::fmt::Debug;

use glam::{Vec2, Vec3};

use crate::distribution::{DirectionSample, DirectionalDistribution};
use crate::error::Error;
use crate::scattering::ScatteringFunction;
use crate::update_rule::{UpdateOutcome, UpdateRule};

/// A learned importance table Q(x, ω) over the scene's surfaces (or volume) and
/// directions, sampled in proportion to Q and updated along every path by Eq. (1).
///
/// The per-vertex flow follows Open PGL's: [`locate`](Self::locate) once, then sample,
/// evaluate the pdf and update as often as needed with the returned region. Every
/// method but [`rebuild_sampling`](Self::rebuild_sampling) takes `&self`, is lock-free,
/// allocates nothing, and may be called from many threads at once.
///
/// Sampling reads a snapshot of Q taken by `rebuild_sampling` (called between passes),
/// so within a pass `sample` and `pdf` describe one fixed distribution exactly while
/// updates accumulate in Q.
pub trait Guide: Sync + Sized {
    /// A located region (e.g. a probe); cheap to copy, valid until the guide changes shape.
    type Region: Copy + Debug + PartialEq + Send + Sync;

    /// A thread's records of one pass, for a guide that learns from them between passes
    /// ([`record`](Self::record), then [`splat`](Self::splat)); `()` for a guide that
    /// learns in place.
    type Records: Default + Debug + Send;

    /// The directional distribution of one region.
    type Distribution<'a>: DirectionalDistribution
    where
        Self: 'a;

    /// The region for a surface point `position` (scene units) with unit normal `normal`
    /// facing the side the path arrives from, or `None` when the guide covers no region
    /// there (the caller then samples its BSDF alone).
    fn locate(&self, position: Vec3, normal: Vec3) -> Option<Self::Region>;

    /// Whether `other` locates every point in the region this guide locates it in (the
    /// same regions, built alike), so that a caller holding both (Q and W of
    /// bidirectional guiding) may locate once for the two. The default says no, which is
    /// always safe; a structure whose regions do not move as it learns (the hemisphere
    /// grid's probes) compares what its `locate` reads.
    fn locates_alike(&self, other: &Self) -> bool {
        let _ = other;
        false
    }

    /// The region's current sampling distribution (the snapshot of the last rebuild).
    fn distribution(&self, region: Self::Region) -> Self::Distribution<'_>;

    /// Draws a direction ∝ Q from two uniform numbers; pdf per steradian.
    fn sample(&self, region: Self::Region, u: Vec2) -> DirectionSample {
        self.distribution(region).sample(u)
    }

    /// The density of `direction` (unit, world space) in the region, per steradian.
    fn pdf(&self, region: Self::Region, direction: Vec3) -> f32 {
        self.distribution(region).pdf(direction)
    }

    /// Blends `target` (radiance, e.g. `Le(y,-ω) + estimate_integral(y, …)`) into
    /// Q(region, direction) with the guide's update rule. NaN, infinite and negative
    /// targets are rejected and counted, never stored.
    fn update(&self, region: Self::Region, direction: Vec3, target: f32) -> UpdateOutcome;

    /// [`update`](Self::update) for a direction the renderer drew with density `pdf`
    /// (per steradian), so that what is learned does not depend on how directions were
    /// drawn: the tables (hemisphere grid, volume) weigh each entry's mean by
    /// [`importance_weight`](crate::importance_weight), the tree records `target / pdf`,
    /// the mixture weights its fit by it. The default ignores `pdf`.
    fn update_sampled(&self, region: Self::Region, direction: Vec3, target: f32, pdf: f32) -> UpdateOutcome {
        let _ = pdf;
        self.update(region, direction, target)
    }

    /// [`update_sampled`](Self::update_sampled) through a thread's own `records`: a guide
    /// that keeps records appends one there (no write the other threads see) and learns
    /// it at [`splat`](Self::splat); the others learn it in place, as `update_sampled`.
    /// The records grow with the pass; kept from pass to pass they stop allocating.
    fn record(
        &self,
        records: &mut Self::Records,
        region: Self::Region,
        direction: Vec3,
        target: f32,
        pdf: f32,
    ) -> UpdateOutcome {
        let _ = records;
        self.update_sampled(region, direction, target, pdf)
    }

    /// Does the part of [`splat`](Self::splat)'s work on `records` that only reads the
    /// guide (the tree maps each record's direction to its cell's square, four at a
    /// time), so that it runs on the threads rather than in the serial splat: call it on
    /// each thread's records after the pass, in parallel. Optional: the splat does what
    /// was not done. The default does nothing.
    fn prepare_splat(&self, records: &mut Self::Records) {
        let _ = records;
    }

    /// Learns a thread's `records` of the pass just traced and empties them (keeping
    /// their room). Call it for every thread's records after the pass and before
    /// [`rebuild_sampling`](Self::rebuild_sampling): records point into the shape the
    /// guide had when they were made. Returns how many records were left out because the
    /// guide changed shape since they were made (0 when called as said).
    fn splat(&mut self, records: &mut Self::Records) -> usize {
        let _ = records;
        0
    }

    /// Estimates `∫ Q(region, ωi) fs(ωi, wo) cos θi dωi` (radiance) with the guide's
    /// [`IntegralEstimator`](crate::IntegralEstimator); `u` jitters stratified estimators.
    fn estimate_integral<S: ScatteringFunction + ?Sized>(
        &self,
        region: Self::Region,
        wo: Vec3,
        bsdf: &S,
        u: Vec2,
    ) -> f32;

    /// The rule it learns by: the learning rate, and the integral estimator the renderer
    /// must follow (under [`IntegralEstimator::PathContinuation`] it carries the path's
    /// own radiance back instead of calling [`estimate_integral`](Self::estimate_integral)).
    ///
    /// [`IntegralEstimator::PathContinuation`]: crate::IntegralEstimator::PathContinuation
    fn update_rule(&self) -> UpdateRule;

    /// Rebuilds every region's sampling distribution from the current Q and starts the
    /// next learning epoch. Call between passes.
    fn rebuild_sampling(&mut self);

    /// Counters and sizes.
    fn stats(&self) -> GuideStats;

    /// Checks every stored value (finite, within range, consistent distributions).
    fn validate(&self) -> Result<(), Error>;

    /// A versioned, checksummed byte image of the learned state.
    fn to_bytes(&self) -> Vec<u8>;

    /// Reads [`to_bytes`](Self::to_bytes)' output. Damaged, truncated or foreign buffers
    /// return an error naming the field and offset; nothing panics.
    fn from_bytes(bytes: &[u8]) -> Result<Self, Error>;

    /// Adds what `other` learned (another process or node rendering the same scene,
    /// typically read back with [`from_bytes`](Self::from_bytes)): both must have been
    /// built over the same scene with the same settings, else nothing changes and
    /// [`Error::Incompatible`] names what differs. Exact where the structure's statistics
    /// are counts and sums (the hemisphere grid under the simple average; the volume and
    /// the tree where both have one shape), a documented approximation elsewhere (each
    /// type's own `merge` says which).
    fn merge(&mut self, other: &Self) -> Result<(), Error>;
}

/// Sizes and counters of a guide.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GuideStats {
    /// Number of regions (probes, cells).
    pub regions: usize,
    /// Directional entries (patches) per region.
    pub entries_per_region: usize,
    /// Bytes held by the guide's tables.
    pub memory_bytes: usize,
    /// Updates accepted since creation (sum of visit counts).
    pub accepted_updates: u64,
    /// Entries that received at least one update.
    pub visited_entries: usize,
    /// Targets rejected for being NaN or infinite.
    pub rejected_non_finite: u64,
    /// Targets rejected for being negative.
    pub rejected_negative: u64,
    /// Learning epochs completed (calls to `rebuild_sampling`).
    pub epochs: u32,
}

/// The counters every table structure keeps: per entry its visits, and the targets it
/// rejected.
#[cfg(any(feature = "hemisphere", feature = "volume"))]
pub(crate) struct TableCounters<'a> {
    /// Updates per entry.
    pub(crate) visits: &'a [core::sync::atomic::AtomicU32],
    /// Targets rejected for being NaN or infinite.
    pub(crate) rejected_non_finite: u64,
    /// Targets rejected for being negative.
    pub(crate) rejected_negative: u64,
}

#[cfg(any(feature = "hemisphere", feature = "volume"))]
impl GuideStats {
    /// The statistics of a structure of `regions` tables of `entries_per_region` entries
    /// each, holding `memory_bytes`, after `epochs` epochs, from its `counters`.
    pub(crate) fn of_tables(
        regions: usize,
        entries_per_region: usize,
        memory_bytes: usize,
        epochs: u32,
        counters: TableCounters<'_>,
    ) -> Self {
        use core::sync::atomic::Ordering;
        let visits = counters.visits.iter().map(|v| v.load(Ordering::Relaxed));
        let (accepted_updates, visited_entries) =
            visits.fold((0u64, 0usize), |(sum, count), v| (sum + v as u64, count + (v > 0) as usize));
        GuideStats {
            regions,
            entries_per_region,
            memory_bytes,
            accepted_updates,
            visited_entries,
            rejected_non_finite: counters.rejected_non_finite,
            rejected_negative: counters.rejected_negative,
            epochs,
        }
    }
}
