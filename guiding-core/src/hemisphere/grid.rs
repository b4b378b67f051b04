//! [`HemisphereGrid`]: probes on the surfaces, each with a hemisphere of Q patches.

use core::cell::OnceCell;
use core::f32::consts::PI;
use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

use alloc::vec::Vec;
use glam::{Vec2, Vec3};

use crate::atomic_f32;
use crate::cdf::build_cdf;
use crate::error::Error;
use crate::frame::Frame;
use crate::geometry::Triangle;
use crate::guide::{Guide, GuideStats, TableCounters};
use crate::q_table::{estimate_row_integral, learn_entry, EntrySlots, TableRow};
use crate::scattering::ScatteringFunction;
use crate::update_rule::{accept_target, importance_weight, UpdateOutcome};

use super::distribution::ProbeDistribution;
use super::probe_lookup::ProbeLookup;
use super::probes::ProbeSet;
use super::settings::HemisphereGridSettings;

/// A probe of a [`HemisphereGrid`]: the region [`Guide::locate`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ProbeId(pub u32);

/// Bytes of a grid's tables for `probes` probes of `patches` patches each, with the
/// struct itself: per probe a position, a normal, two visit counts and the Lambertian
/// sum (36 bytes); per patch Q, a visit count, a weight sum and a CDF entry (16 bytes);
/// the lookup's bucket and candidate tables; and the shared per-patch centre and cosine tables (16
/// bytes per patch).
pub(crate) fn table_bytes(probes: usize, patches: usize) -> usize {
    let per_probe = 3 * 4 + 3 * 4 + 3 * 4 + patches * 16;
    probes.saturating_mul(per_probe)
        + ProbeLookup::bytes_for(probes)
        + patches * 16
        + core::mem::size_of::<HemisphereGrid>()
}

/// Dahm & Keller's importance table: probes at low-discrepancy points on the scene's
/// surfaces, each holding a hemisphere of equal-area patches with one Q value
/// (radiance) per patch.
///
/// A hit uses the nearest probe whose normal is within
/// [`max_normal_angle_deg`](HemisphereGridSettings::max_normal_angle_deg) of its own
/// (Voronoi cells on the surface, found through a hash grid). When no such probe lies
/// within [`max_search_rings`](HemisphereGridSettings::max_search_rings) lookup cells,
/// [`locate`](Guide::locate) returns `None` and the caller samples its BSDF alone there.
///
/// # Layout
///
/// Structure of arrays, all flat and exposed as slices for GPU upload or a C caller:
/// probe `p`'s patch `k` lives at index `p·N + k` of [`q_values`](Self::q_values),
/// [`visit_counts`](Self::visit_counts) and [`cdf`](Self::cdf), with N =
/// [`patch_count`](Self::patch_count); probe arrays are indexed by `p`, sorted by lookup
/// bucket (see [`ProbeLookup`]). Q is f32 bits in `AtomicU32`; the CDF is the snapshot
/// of the last [`rebuild_sampling`](Guide::rebuild_sampling).
///
/// ```
/// use guiding_core::{Guide, HemisphereGrid, HemisphereGridSettings, Lambertian, Triangle};
/// use glam::{Vec2, Vec3};
///
/// let floor = [
///     Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(-1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0)),
///     Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0)),
/// ];
/// let mut grid = HemisphereGrid::build(&floor, HemisphereGridSettings::default())?;
/// let probe = grid.locate(Vec3::new(0.2, 0.0, 0.1), Vec3::Y).expect("a probe faces up");
/// // Light arrives from straight above: teach the probe, then sample it.
/// for _ in 0..100 {
///     grid.update(probe, Vec3::Y, 10.0);
/// }
/// grid.rebuild_sampling();
/// let sample = grid.sample(probe, Vec2::new(0.5, 0.5));
/// assert!(sample.pdf > 0.0 && sample.direction.y > 0.0);
/// // The learned Q also answers the integral of Eq. (1) for a diffuse surface.
/// let bsdf = Lambertian { normal: Vec3::Y, albedo: 0.5 };
/// assert!(grid.estimate_integral(probe, Vec3::Y, &bsdf, Vec2::ZERO) > 0.0);
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Debug)]
pub struct HemisphereGrid {
    pub(crate) settings: HemisphereGridSettings,
    pub(crate) cos_max_normal_angle: f32,
    pub(crate) probe_spacing: f32,
    pub(crate) positions: Vec<Vec3>,
    pub(crate) normals: Vec<Vec3>,
    pub(crate) probe_visits: Vec<AtomicU32>,
    /// Each probe's visit count when its CDF was last built: a probe whose count has
    /// not moved since has nothing new to sample from and is skipped by the rebuild.
    pub(crate) visits_at_last_build: Vec<u32>,
    /// Per probe Σ_k Q_k·∫_k cos θ dω (f32 bits): kept current by every update, made exact
    /// again at every rebuild, so a Lambertian integral estimate costs one load.
    pub(crate) lambertian_sums: Vec<AtomicU32>,
    pub(crate) q: Vec<AtomicU32>,
    pub(crate) patch_visits: Vec<AtomicU32>,
    /// Per patch Σ of the importance weights of its updates (f32 bits): the simple
    /// average's denominator, so that each patch learns its mean over its solid angle
    /// whatever density drew the directions.
    pub(crate) patch_weights: Vec<AtomicU32>,
    pub(crate) cdf: Vec<f32>,
    pub(crate) lookup: ProbeLookup,
    pub(crate) patch_centers: Vec<Vec3>,
    pub(crate) patch_cos_integrals: Vec<f32>,
    pub(crate) epoch: u32,
    pub(crate) rejected_non_finite: AtomicUsize,
    pub(crate) rejected_negative: AtomicUsize,
}

/// The learned state a grid is assembled from (fresh or decoded).
pub(crate) struct GridState {
    pub(crate) probe_spacing: f32,
    pub(crate) positions: Vec<Vec3>,
    pub(crate) normals: Vec<Vec3>,
    pub(crate) probe_visits: Vec<u32>,
    pub(crate) q: Vec<f32>,
    pub(crate) patch_visits: Vec<u32>,
    pub(crate) cdf: Option<Vec<f32>>,
    pub(crate) epoch: u32,
    pub(crate) rejected_non_finite: usize,
    pub(crate) rejected_negative: usize,
}

impl HemisphereGrid {
    /// Places as many probes as the budget allows (or `settings.probe_count`) on
    /// `triangles` in proportion to area, and sets every Q to `settings.initial_q`.
    pub fn build(triangles: &[Triangle], settings: HemisphereGridSettings) -> Result<Self, Error> {
        let count = settings.resolve_probe_count()?;
        let probes = ProbeSet::place_on_triangles(triangles, count, settings.two_sided)?;
        Self::from_probes(&probes, settings)
    }

    /// A grid over probes the caller placed. Normals are normalised; a non-finite
    /// position or a zero-length normal is an error naming the probe.
    pub fn from_probes(probes: &ProbeSet, settings: HemisphereGridSettings) -> Result<Self, Error> {
        settings.validate()?;
        if probes.is_empty() {
            return Err(Error::NoSurface);
        }
        let budget = settings.budget_bytes;
        let needed = settings.memory_bytes(probes.len());
        if needed > budget || probes.len() > super::settings::MAX_PROBES {
            return Err(Error::OverBudget { regions: probes.len(), needed_bytes: needed, budget_bytes: budget });
        }
        if probes.normals.len() != probes.len() {
            return Err(Error::InvalidProbe {
                index: probes.normals.len().min(probes.len()),
                reason: "positions and normals differ in count",
            });
        }
        let mut normals = Vec::with_capacity(probes.len());
        for (index, (p, n)) in probes.positions.iter().zip(&probes.normals).enumerate() {
            if !p.is_finite() {
                return Err(Error::InvalidProbe { index, reason: "position is NaN or infinite" });
            }
            match n.try_normalize() {
                Some(unit) => normals.push(unit),
                None => return Err(Error::InvalidProbe { index, reason: "normal is zero, NaN or infinite" }),
            }
        }
        let entries = probes.len() * settings.layout.patch_count();
        let state = GridState {
            probe_spacing: probes.spacing,
            positions: probes.positions.clone(),
            normals,
            probe_visits: alloc::vec![0; probes.len()],
            q: alloc::vec![settings.initial_q; entries],
            patch_visits: alloc::vec![0; entries],
            cdf: None,
            epoch: 0,
            rejected_non_finite: 0,
            rejected_negative: 0,
        };
        Ok(Self::assemble(settings, state))
    }

    /// Builds the lookup, stores the probes in lookup order and, unless the state brings
    /// its CDF snapshot, builds the CDFs from Q.
    pub(crate) fn assemble(settings: HemisphereGridSettings, state: GridState) -> Self {
        let patches = settings.layout.patch_count();
        let (lookup, order) = ProbeLookup::build(&state.positions, state.probe_spacing, settings.max_search_rings);
        // Every table is built with its exact capacity, so memory_bytes() is what the
        // budget accounted for.
        let reorder_probe = |values: &[Vec3]| order.iter().map(|&i| values[i as usize]).collect::<Vec<_>>();
        let reorder_rows = |values: &[f32]| -> Vec<f32> {
            let mut rows = Vec::with_capacity(values.len());
            for &i in &order {
                rows.extend_from_slice(&values[i as usize * patches..(i as usize + 1) * patches]);
            }
            rows
        };
        let to_atomic_f32 = |values: Vec<f32>| values.into_iter().map(atomic_f32::new).collect::<Vec<_>>();
        // Weights are not serialized: a decoded grid goes on as if every earlier update
        // had weighed 1 (its visit count).
        let weights: Vec<f32> = state.patch_visits.iter().map(|&v| v as f32).collect();
        let visits_in_order = |values: &[u32], width: usize| -> Vec<AtomicU32> {
            let mut rows = Vec::with_capacity(values.len());
            for &i in &order {
                rows.extend(values[i as usize * width..(i as usize + 1) * width].iter().map(|&v| AtomicU32::new(v)));
            }
            rows
        };
        let (patch_centers, patch_cos_integrals) = settings.layout.patch_tables();
        let cdf = state.cdf.as_deref().map(reorder_rows);
        let has_cdf = cdf.is_some();
        let mut grid = Self {
            cos_max_normal_angle: libm::cosf(settings.max_normal_angle_deg.to_radians()),
            probe_spacing: state.probe_spacing,
            positions: reorder_probe(&state.positions),
            normals: reorder_probe(&state.normals),
            probe_visits: visits_in_order(&state.probe_visits, 1),
            visits_at_last_build: order.iter().map(|&i| state.probe_visits[i as usize]).collect(),
            lambertian_sums: order.iter().map(|_| atomic_f32::new(0.0)).collect(),
            q: to_atomic_f32(reorder_rows(&state.q)),
            patch_visits: visits_in_order(&state.patch_visits, patches),
            patch_weights: to_atomic_f32(reorder_rows(&weights)),
            cdf: cdf.unwrap_or_else(|| alloc::vec![0.0; state.q.len()]),
            lookup,
            patch_centers,
            patch_cos_integrals,
            epoch: state.epoch,
            rejected_non_finite: AtomicUsize::new(state.rejected_non_finite),
            rejected_negative: AtomicUsize::new(state.rejected_negative),
            settings,
        };
        if has_cdf {
            for probe in 0..grid.probe_count() {
                grid.refresh_lambertian_sum(ProbeId(probe as u32));
            }
        } else {
            grid.build_cdfs(true);
        }
        grid
    }

    /// Recomputes a probe's Lambertian sum exactly from its Q.
    fn refresh_lambertian_sum(&self, probe: ProbeId) {
        let sum = weighted_sum(self.q_row(probe), &self.patch_cos_integrals).min(f32::MAX as f64) as f32;
        self.lambertian_sums[probe.0 as usize].store(sum.to_bits(), Ordering::Relaxed);
    }

    /// Rebuilds the CDF (and refreshes the Lambertian sum) of every probe updated since
    /// its last build, or of all with `all`.
    pub(crate) fn build_cdfs(&mut self, all: bool) {
        let patches = self.patch_count();
        let mix = self.settings.uniform_mix;
        let exponent = self.settings.sampling_exponent;
        let cosine_product = self.settings.cosine_product;
        let rows = self.cdf.chunks_exact_mut(patches).zip(self.q.chunks_exact(patches));
        let counts = self.probe_visits.iter().zip(&mut self.visits_at_last_build).zip(&self.lambertian_sums);
        for ((cdf, q), ((visits, built), sum)) in rows.zip(counts) {
            let visits = visits.load(Ordering::Relaxed);
            if all || visits != *built {
                let cosine = |k: usize| if cosine_product { self.patch_cos_integrals[k] } else { 1.0 };
                if exponent == 1.0 {
                    build_cdf(cdf, mix, |k| atomic_f32::load(&q[k]) * cosine(k));
                } else {
                    build_cdf(cdf, mix, |k| libm::powf(atomic_f32::load(&q[k]), exponent) * cosine(k));
                }
                let exact = weighted_sum(q, &self.patch_cos_integrals).min(f32::MAX as f64) as f32;
                sum.store(exact.to_bits(), Ordering::Relaxed);
                *built = visits;
            }
        }
    }

    /// The settings the grid was built with.
    pub fn settings(&self) -> &HemisphereGridSettings {
        &self.settings
    }

    /// Number of probes.
    pub fn probe_count(&self) -> usize {
        self.positions.len()
    }

    /// Patches per probe (N).
    pub fn patch_count(&self) -> usize {
        self.patch_centers.len()
    }

    /// Learning epochs completed (calls to `rebuild_sampling`).
    pub fn epoch(&self) -> u32 {
        self.epoch
    }

    /// Per patch ∫ cos θ dω over it (steradians): the Lambertian weights.
    pub fn patch_cos_integrals(&self) -> &[f32] {
        &self.patch_cos_integrals
    }

    /// Per probe Σ_k Q_k·∫_k cos θ dω (f32 bits), kept current by every update.
    pub fn lambertian_sums(&self) -> &[AtomicU32] {
        &self.lambertian_sums
    }

    /// Probe positions, scene units, in storage order.
    pub fn probe_positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Probe unit normals, in storage order.
    pub fn probe_normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Q per patch (f32 bits), probe-major: entry `p·N + k`.
    pub fn q_values(&self) -> &[AtomicU32] {
        &self.q
    }

    /// Accepted updates per patch, probe-major.
    pub fn visit_counts(&self) -> &[AtomicU32] {
        &self.patch_visits
    }

    /// Accepted updates per probe.
    pub fn probe_visit_counts(&self) -> &[AtomicU32] {
        &self.probe_visits
    }

    /// Sampling CDFs, probe-major: N entries per probe, each a multiple of 2⁻²⁴, the last 1.
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// The probe lookup (hash grid).
    pub fn lookup(&self) -> &ProbeLookup {
        &self.lookup
    }

    /// Typical distance between neighbouring probes, scene units.
    pub fn probe_spacing(&self) -> f32 {
        self.probe_spacing
    }

    /// The current Q of a probe's patch (radiance).
    pub fn q(&self, probe: ProbeId, patch: usize) -> f32 {
        atomic_f32::load(&self.q[probe.0 as usize * self.patch_count() + patch])
    }

    /// Sets every Q of `probe` from `values` (radiance, one per patch), clamped to
    /// `[q_floor, f32::MAX]`; NaN becomes the floor. For tests, tools and restoring
    /// tables learned elsewhere; sampling follows after the next rebuild.
    pub fn set_q_values(&mut self, probe: ProbeId, values: &[f32]) {
        let floor = self.settings.q_floor;
        let patches = self.patch_count();
        let start = probe.0 as usize * patches;
        for (cell, &v) in self.q[start..start + patches].iter_mut().zip(values) {
            let clamped = if v.is_nan() { floor } else { v.clamp(floor, f32::MAX) };
            *cell = atomic_f32::new(clamped);
        }
        // Make the next rebuild include this probe.
        let built = &mut self.visits_at_last_build[probe.0 as usize];
        *built = built.wrapping_add(1);
        self.refresh_lambertian_sum(probe);
    }

    /// Bytes held by all tables and the struct.
    pub fn memory_bytes(&self) -> usize {
        let per_probe = self.positions.capacity() * 12
            + self.normals.capacity() * 12
            + (self.probe_visits.capacity() + self.visits_at_last_build.capacity() + self.lambertian_sums.capacity())
                * 4;
        let per_patch =
            (self.q.capacity() + self.patch_visits.capacity() + self.patch_weights.capacity() + self.cdf.capacity())
                * 4;
        let shared = self.patch_centers.capacity() * 12 + self.patch_cos_integrals.capacity() * 4;
        per_probe + per_patch + shared + self.lookup.memory_bytes() + core::mem::size_of::<Self>()
    }

    fn frame(&self, probe: ProbeId) -> Frame {
        Frame::from_normal(self.normals[probe.0 as usize])
    }

    fn q_row(&self, probe: ProbeId) -> &[AtomicU32] {
        let patches = self.patch_count();
        let start = probe.0 as usize * patches;
        &self.q[start..start + patches]
    }

    pub(crate) fn state_for_serialization(&self) -> GridStateView<'_> {
        GridStateView {
            probe_spacing: self.probe_spacing,
            positions: &self.positions,
            normals: &self.normals,
            probe_visits: &self.probe_visits,
            q: &self.q,
            patch_visits: &self.patch_visits,
            cdf: &self.cdf,
            epoch: self.epoch,
            rejected_non_finite: self.rejected_non_finite.load(Ordering::Relaxed),
            rejected_negative: self.rejected_negative.load(Ordering::Relaxed),
        }
    }
}

/// Borrowed learned state, for serialization.
pub(crate) struct GridStateView<'a> {
    pub(crate) probe_spacing: f32,
    pub(crate) positions: &'a [Vec3],
    pub(crate) normals: &'a [Vec3],
    pub(crate) probe_visits: &'a [AtomicU32],
    pub(crate) q: &'a [AtomicU32],
    pub(crate) patch_visits: &'a [AtomicU32],
    pub(crate) cdf: &'a [f32],
    pub(crate) epoch: u32,
    pub(crate) rejected_non_finite: usize,
    pub(crate) rejected_negative: usize,
}

/// Σ q_k·w_k with eight independent f32 partial sums, so the additions pipeline instead
/// of waiting on each other; the partial sums are combined in f64. A partial sum can
/// overflow only when Q is within a factor N/2π of f32::MAX, and the caller clamps the
/// result to f32::MAX.
fn weighted_sum(q: &[AtomicU32], weights: &[f32]) -> f64 {
    let mut partial = [0.0f32; 8];
    let (q_chunks, w_chunks) = (q.chunks_exact(8), weights.chunks_exact(8));
    let tail: f64 = q_chunks
        .remainder()
        .iter()
        .zip(w_chunks.remainder())
        .map(|(q, &w)| atomic_f32::load(q) as f64 * w as f64)
        .sum();
    for (q8, w8) in q_chunks.zip(w_chunks) {
        for lane in 0..8 {
            partial[lane] += atomic_f32::load(&q8[lane]) * w8[lane];
        }
    }
    partial.iter().map(|&p| p as f64).sum::<f64>() + tail
}

impl HemisphereGrid {
    /// Learns `target` for `direction`, the update weighing `weight` (1 unweighted).
    fn update_weighted(&self, probe: ProbeId, direction: Vec3, target: f32, weight: f32) -> UpdateOutcome {
        let target = match accept_target(target, &self.rejected_negative, &self.rejected_non_finite) {
            Ok(t) => t,
            Err(rejected) => return rejected,
        };
        let Some(patch) = self.settings.layout.patch_of(self.frame(probe).to_local(direction)) else {
            return UpdateOutcome::OutsideDomain;
        };
        let index = probe.0 as usize * self.patch_count() + patch;
        let slots = EntrySlots {
            q: &self.q[index],
            visits: &self.patch_visits[index],
            weights: &self.patch_weights[index],
            region_visits: &self.probe_visits[probe.0 as usize],
        };
        let rule = &self.settings.update_rule;
        let (previous, stored) = learn_entry(slots, target, weight, rule, self.epoch, self.settings.q_floor);
        let change = (stored as f64 - previous as f64) * self.patch_cos_integrals[patch] as f64;
        if change != 0.0 {
            atomic_f32::update(&self.lambertian_sums[probe.0 as usize], |sum| {
                (sum as f64 + change).min(f32::MAX as f64) as f32
            });
        }
        UpdateOutcome::Accepted
    }
}

/// One probe's row: its hemisphere of patches in the probe's frame, built only where an
/// estimator turns directions (a Lambertian estimate needs none, and the frame's division
/// was most of its cost).
struct ProbeRow<'a> {
    grid: &'a HemisphereGrid,
    probe: ProbeId,
    frame: OnceCell<Frame>,
}

impl ProbeRow<'_> {
    fn frame(&self) -> &Frame {
        self.frame.get_or_init(|| self.grid.frame(self.probe))
    }
}

impl TableRow for ProbeRow<'_> {
    fn q(&self) -> &[AtomicU32] {
        self.grid.q_row(self.probe)
    }

    fn entry_solid_angle(&self) -> f64 {
        self.grid.settings.layout.patch_solid_angle() as f64
    }

    fn entry_of(&self, wi: Vec3) -> Option<usize> {
        self.grid.settings.layout.patch_of(self.frame().to_local(wi))
    }

    fn center(&self, k: usize) -> Vec3 {
        self.frame().to_world(self.grid.patch_centers[k])
    }

    fn center_cos(&self, k: usize) -> f32 {
        self.grid.patch_centers[k].z
    }

    fn direction_in_entry(&self, k: usize, u: Vec2) -> Vec3 {
        self.frame().to_world(self.grid.settings.layout.direction_in_patch(k, u))
    }

    /// From the running Σ_k Q_k·∫_k cos dω: one load.
    fn lambertian_integral(&self, albedo: f32) -> f64 {
        let sum = atomic_f32::load(&self.grid.lambertian_sums[self.probe.0 as usize]).max(0.0);
        albedo as f64 / core::f64::consts::PI * sum as f64
    }
}

impl Guide for HemisphereGrid {
    type Records = ();
    type Region = ProbeId;
    type Distribution<'a> = ProbeDistribution<'a>;

    fn locate(&self, position: Vec3, normal: Vec3) -> Option<ProbeId> {
        let normal = normal.try_normalize()?;
        if !position.is_finite() {
            return None;
        }
        let cos_max = self.cos_max_normal_angle;
        self.lookup
            .nearest(position, &self.positions, |p| self.normals[p].dot(normal) >= cos_max)
            .map(|p| ProbeId(p as u32))
    }

    fn locates_alike(&self, other: &Self) -> bool {
        // What `locate` reads: the normal test, the probes and their lookup.
        self.cos_max_normal_angle == other.cos_max_normal_angle
            && self.positions == other.positions
            && self.normals == other.normals
            && self.lookup == other.lookup
    }

    fn distribution(&self, probe: ProbeId) -> ProbeDistribution<'_> {
        let patches = self.patch_count();
        let start = probe.0 as usize * patches;
        ProbeDistribution {
            cdf: &self.cdf[start..start + patches],
            frame: self.frame(probe),
            layout: self.settings.layout,
        }
    }

    fn update(&self, probe: ProbeId, direction: Vec3, target: f32) -> UpdateOutcome {
        self.update_weighted(probe, direction, target, 1.0)
    }

    /// Weighs the update by the density the direction was drawn with (see
    /// [`importance_weight`]): each patch learns its mean over its solid angle.
    fn update_sampled(&self, probe: ProbeId, direction: Vec3, target: f32, pdf: f32) -> UpdateOutcome {
        match importance_weight(0.5 / PI, pdf) {
            Some(weight) => self.update_weighted(probe, direction, target, weight),
            None => UpdateOutcome::OutsideDomain,
        }
    }

    fn estimate_integral<S: ScatteringFunction + ?Sized>(&self, probe: ProbeId, wo: Vec3, bsdf: &S, u: Vec2) -> f32 {
        let row = ProbeRow { grid: self, probe, frame: OnceCell::new() };
        estimate_row_integral(self.settings.update_rule.integral, &row, bsdf, wo, u)
    }

    fn update_rule(&self) -> crate::update_rule::UpdateRule {
        self.settings.update_rule
    }

    fn rebuild_sampling(&mut self) {
        self.build_cdfs(false);
        self.epoch = self.epoch.saturating_add(1);
    }

    fn stats(&self) -> GuideStats {
        let counters = TableCounters {
            visits: &self.patch_visits,
            rejected_non_finite: self.rejected_non_finite.load(Ordering::Relaxed) as u64,
            rejected_negative: self.rejected_negative.load(Ordering::Relaxed) as u64,
        };
        GuideStats::of_tables(self.probe_count(), self.patch_count(), self.memory_bytes(), self.epoch, counters)
    }

    fn validate(&self) -> Result<(), Error> {
        let invalid = |field: &'static str, index: usize, requirement: &'static str| {
            Err(Error::Decode(crate::error::DecodeError::InvalidField { field, index, requirement }))
        };
        for (i, p) in self.positions.iter().enumerate() {
            if !p.is_finite() {
                return invalid("positions", i, "finite");
            }
        }
        for (i, n) in self.normals.iter().enumerate() {
            if !n.is_finite() || (n.length() - 1.0).abs() > 1e-3 {
                return invalid("normals", i, "finite and unit length");
            }
        }
        crate::table_checks::check_q(&self.q, self.settings.q_floor)?;
        crate::table_checks::check_cdf_rows(&self.cdf, self.patch_count())
    }

    fn to_bytes(&self) -> Vec<u8> {
        super::serialize::encode(self)
    }

    fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        super::serialize::decode(bytes)
    }

    fn merge(&mut self, other: &Self) -> Result<(), Error> {
        HemisphereGrid::merge(self, other)
    }
}

#[cfg(test)]
pub(super) mod tests;
