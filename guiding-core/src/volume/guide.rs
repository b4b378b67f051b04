//! [`IrradianceVolume`]: full-sphere tables of Q at the leaves of an adaptive octree
//! over the scene, found by position alone.

use alloc::vec::Vec;
use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

use glam::{Vec2, Vec3};

use crate::atomic_f32;
use crate::cdf::build_cdf;
use crate::cell_grid::CellGrid;
use crate::error::Error;
use crate::guide::{Guide, GuideStats, TableCounters};
use crate::q_table::{estimate_row_integral, learn_entry, EntrySlots, TableRow};
use crate::scattering::ScatteringFunction;
use crate::update_rule::{accept_target, importance_weight, UpdateOutcome};

use super::distribution::VolumeDistribution;
use super::irradiance_sh;
use super::settings::{IrradianceVolumeSettings, BYTES_PER_NODE};

/// Marks a node entry as a leaf (the low bits are its leaf index); otherwise the entry is
/// the index of the node's first of eight children.
pub(crate) const LEAF: u32 = 1 << 31;

/// A located region of an [`IrradianceVolume`]: the leaf holding the point, and the
/// normal whose hemisphere sampling folds the sphere onto.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeRegion {
    /// Index of the leaf (its table).
    pub leaf: u32,
    /// Unit normal of the surface point, facing the side the path arrives from.
    pub normal: Vec3,
}

/// Q(x, ω) in full-sphere tables of equal-area patches at the leaves of an octree over
/// the scene's bounds (Greger et al.'s irradiance volume, with Q in place of radiance):
/// lookup by position only, so one table serves every surface that passes through its
/// leaf, whatever their normals.
///
/// The tree starts as a regular grid taking `initial_share` of the byte budget; between
/// passes, leaves that took at least `split_updates_per_patch × patches` updates since
/// they were made split into eight children (most-updated first, while the budget
/// lasts), each inheriting the parent's Q and an eighth of its visit counts. So memory
/// goes where paths go.
///
/// Sampling at a surface folds the sphere onto the normal's hemisphere: a direction drawn
/// ∝ Q below the surface is mirrored across the tangent plane, and the pdf of ω above it
/// is p(ω) + p(mirror(ω)). That is exact, keeps every upper direction's pdf ≥
/// `uniform_mix/(4π)`, and needs no per-normal normalisation of the table.
///
/// ```
/// use guiding_core::volume::{IrradianceVolume, IrradianceVolumeSettings};
/// use guiding_core::{Guide, Pcg32};
/// use glam::Vec3;
/// let mut guide = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, IrradianceVolumeSettings::default()).unwrap();
/// let region = guide.locate(Vec3::splat(0.5), Vec3::Y).unwrap();
/// let mut rng = Pcg32::new(1, 1);
/// for _ in 0..20_000 {
///     let s = guide.sample(region, rng.next_vec2());
///     guide.update(region, s.direction, 10.0 * s.direction.x.max(0.0).powi(8));
/// }
/// guide.rebuild_sampling();
/// assert!(guide.pdf(region, Vec3::new(0.9, 0.43, 0.0).normalize()) > 5.0 * guide.pdf(region, Vec3::Y));
/// ```
pub struct IrradianceVolume {
    pub(crate) settings: IrradianceVolumeSettings,
    pub(crate) low: Vec3,
    pub(crate) high: Vec3,
    pub(crate) grid: CellGrid,
    /// The tree: the grid's cells first, then every split's eight children in a row.
    pub(crate) nodes: Vec<u32>,
    pub(crate) q: Vec<AtomicU32>,
    pub(crate) patch_visits: Vec<AtomicU32>,
    /// Per patch Σ of the importance weights of its updates (f32 bits), the simple
    /// average's denominator (see [`importance_weight`]).
    pub(crate) patch_weights: Vec<AtomicU32>,
    pub(crate) leaf_visits: Vec<AtomicU32>,
    /// Leaf visits when its CDF was last built (unchanged leaves are not rebuilt).
    pub(crate) visits_at_build: Vec<u32>,
    pub(crate) cdf: Vec<f32>,
    /// Per leaf, its Q at the last CDF build projected on order-2 spherical harmonics:
    /// the Lambertian integral estimate for any normal in nine terms.
    pub(crate) irradiance: Vec<[f32; 9]>,
    pub(crate) patch_centers: Vec<Vec3>,
    /// ∫ Y_lm dω over each patch, shared by every leaf's projection.
    pub(crate) patch_basis: Vec<[f32; 9]>,
    pub(crate) epoch: u32,
    pub(crate) rejected_non_finite: AtomicUsize,
    pub(crate) rejected_negative: AtomicUsize,
}

/// The pieces of a volume, as serialization reads and writes them.
pub(crate) struct VolumeState {
    pub(crate) nodes: Vec<u32>,
    pub(crate) q: Vec<f32>,
    pub(crate) patch_visits: Vec<u32>,
    pub(crate) leaf_visits: Vec<u32>,
    pub(crate) cdf: Vec<f32>,
    pub(crate) irradiance: Vec<[f32; 9]>,
    pub(crate) epoch: u32,
    pub(crate) rejected_non_finite: usize,
    pub(crate) rejected_negative: usize,
}

impl IrradianceVolume {
    /// A volume over `low..high` (scene units; points outside use the nearest cell),
    /// every patch at `initial_q`.
    pub fn new(low: Vec3, high: Vec3, settings: IrradianceVolumeSettings) -> Result<Self, Error> {
        let grid = Self::grid_for(low, high, &settings)?;
        let leaves = grid.cell_count();
        let patches = settings.layout.patch_count();
        let state = VolumeState {
            nodes: (0..leaves as u32).map(|leaf| LEAF | leaf).collect(),
            q: alloc::vec![settings.initial_q; leaves * patches],
            patch_visits: alloc::vec![0; leaves * patches],
            leaf_visits: alloc::vec![0; leaves],
            cdf: alloc::vec![0.0; leaves * patches],
            irradiance: alloc::vec![[0.0; 9]; leaves],
            epoch: 0,
            rejected_non_finite: 0,
            rejected_negative: 0,
        };
        let mut volume = Self::assemble(low, high, settings, grid, state);
        volume.build_cdfs(true);
        Ok(volume)
    }

    /// The initial grid `new` lays over `low..high` (checks the settings; allocates
    /// nothing).
    pub(crate) fn grid_for(low: Vec3, high: Vec3, settings: &IrradianceVolumeSettings) -> Result<CellGrid, Error> {
        settings.validate()?;
        let tables = settings.budget_bytes.saturating_sub(settings.shared_bytes());
        let initial = (tables as f64 * settings.initial_share as f64) as usize;
        let per_cell = settings.bytes_per_leaf() + BYTES_PER_NODE;
        // A grid given by hand must fit the whole budget; one sized here, its share.
        let budget = if settings.resolution.is_some() { tables } else { initial.max(per_cell) };
        let grid = CellGrid::new(low, high, settings.resolution, budget, per_cell)?;
        if grid.cell_count() * per_cell + settings.shared_bytes() > settings.budget_bytes {
            let needed_bytes = grid.cell_count() * per_cell + settings.shared_bytes();
            return Err(Error::BudgetTooSmall { budget_bytes: settings.budget_bytes, needed_bytes });
        }
        Ok(grid)
    }

    /// A volume from its parts (decoded, or fresh); the CDF is taken as given.
    pub(crate) fn assemble(
        low: Vec3,
        high: Vec3,
        settings: IrradianceVolumeSettings,
        grid: CellGrid,
        state: VolumeState,
    ) -> Self {
        let layout = settings.layout;
        let atomics = |values: &[u32]| values.iter().map(|&v| AtomicU32::new(v)).collect::<Vec<_>>();
        Self {
            settings,
            low,
            high,
            grid,
            nodes: state.nodes,
            q: state.q.iter().map(|&q| atomic_f32::new(q)).collect(),
            patch_visits: atomics(&state.patch_visits),
            // Weights are not serialized: a decoded volume goes on as if every earlier
            // update had weighed 1 (its visit count).
            patch_weights: state.patch_visits.iter().map(|&v| atomic_f32::new(v as f32)).collect(),
            visits_at_build: state.leaf_visits.clone(),
            leaf_visits: atomics(&state.leaf_visits),
            cdf: state.cdf,
            irradiance: state.irradiance,
            patch_centers: (0..layout.patch_count()).map(|k| layout.direction_in_patch(k, Vec2::splat(0.5))).collect(),
            patch_basis: irradiance_sh::patch_basis_integrals(&layout),
            epoch: state.epoch,
            rejected_non_finite: AtomicUsize::new(state.rejected_non_finite),
            rejected_negative: AtomicUsize::new(state.rejected_negative),
        }
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &IrradianceVolumeSettings {
        &self.settings
    }

    /// The box the tree covers.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.low, self.high)
    }

    /// The initial grid's cells along x, y and z.
    pub fn resolution(&self) -> [u32; 3] {
        self.grid.resolution()
    }

    /// Number of leaves (tables).
    pub fn leaf_count(&self) -> usize {
        self.leaf_visits.len()
    }

    /// Number of tree nodes (the grid's cells and every split's children).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Patches per leaf.
    pub fn patch_count(&self) -> usize {
        self.patch_centers.len()
    }

    /// Q of `patch` in `leaf`.
    pub fn q(&self, leaf: u32, patch: usize) -> f32 {
        atomic_f32::load(&self.q[leaf as usize * self.patch_count() + patch])
    }

    /// Every Q, leaf after leaf (f32 bits).
    pub fn q_values(&self) -> &[AtomicU32] {
        &self.q
    }

    /// Per patch of every leaf, the updates it took (leaf after leaf).
    pub fn patch_visit_counts(&self) -> &[AtomicU32] {
        &self.patch_visits
    }

    /// Per leaf, the updates it took since it was made (splitting shares a parent's
    /// count among its children).
    pub fn leaf_visit_counts(&self) -> &[AtomicU32] {
        &self.leaf_visits
    }

    /// The tree: the initial grid's cells first (x fastest, then y, then z), then every
    /// split's eight children in a row, ordered by octant (bit 0 x, bit 1 y, bit 2 z set
    /// for the upper half). An entry with [`LEAF_BIT`](Self::LEAF_BIT) set is a leaf and
    /// its low bits are the leaf's index; any other is the index of its first child.
    pub fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Marks a [`nodes`](Self::nodes) entry as a leaf.
    pub const LEAF_BIT: u32 = LEAF;

    /// The initial grid's low corner and its cells per unit length along each axis: a
    /// point's cell coordinates are `(position - low) * inverse_cell_size`, clamped to
    /// the grid.
    pub fn grid_transform(&self) -> (Vec3, Vec3) {
        self.grid.transform()
    }

    /// Every leaf's sampling CDF over its patches, as of the last rebuild (leaf after
    /// leaf; guiding-core's [`cdf`](crate::cdf) layout).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// Per leaf, its Q at the last rebuild projected on the nine real spherical
    /// harmonics of order ≤ 2 (radiance × sr): the Lambertian integral's source.
    pub fn irradiance_coefficients(&self) -> &[[f32; 9]] {
        &self.irradiance
    }

    /// Per patch, ∫ Y_lm dω over it (sr), shared by every leaf's projection: the
    /// projection is L_lm = Σ_patches Q·these.
    pub fn patch_basis_integrals(&self) -> &[[f32; 9]] {
        &self.patch_basis
    }

    /// Overwrites a leaf's Q table (clamped to `[q_floor, f32::MAX]`, non-finite values
    /// to the floor); takes effect at the next rebuild.
    pub fn set_q_values(&mut self, leaf: u32, values: &[f32]) {
        let patches = self.patch_count();
        let floor = self.settings.q_floor;
        for (slot, &v) in self.q[leaf as usize * patches..(leaf as usize + 1) * patches].iter().zip(values) {
            let v = if v.is_finite() { v.clamp(floor, f32::MAX) } else { floor };
            slot.store(v.to_bits(), Ordering::Relaxed);
        }
        // Make the leaf look changed, so the next rebuild builds its CDF.
        self.visits_at_build[leaf as usize] = u32::MAX;
    }

    /// Bytes held by the tables, the tree and the per-patch tables all leaves share.
    pub fn memory_bytes(&self) -> usize {
        self.leaf_count() * self.settings.bytes_per_leaf()
            + self.nodes.len() * BYTES_PER_NODE
            + self.settings.shared_bytes()
    }

    /// The state, for serialization.
    pub(crate) fn state(&self) -> VolumeState {
        let load = |values: &[AtomicU32]| values.iter().map(|v| v.load(Ordering::Relaxed)).collect::<Vec<_>>();
        VolumeState {
            nodes: self.nodes.clone(),
            q: self.q.iter().map(atomic_f32::load).collect(),
            patch_visits: load(&self.patch_visits),
            leaf_visits: load(&self.leaf_visits),
            cdf: self.cdf.clone(),
            irradiance: self.irradiance.clone(),
            epoch: self.epoch,
            rejected_non_finite: self.rejected_non_finite.load(Ordering::Relaxed),
            rejected_negative: self.rejected_negative.load(Ordering::Relaxed),
        }
    }

    /// The leaf holding `position`: down the tree from its grid cell by octants.
    #[inline]
    fn leaf_at(&self, position: Vec3) -> Option<u32> {
        let (cell, mut offset) = self.grid.cell_and_offset(position)?;
        let mut entry = self.nodes[cell as usize];
        while entry & LEAF == 0 {
            let upper = offset.cmpge(Vec3::splat(0.5));
            let octant = upper.x as u32 | (upper.y as u32) << 1 | (upper.z as u32) << 2;
            offset = offset * 2.0 - Vec3::select(upper, Vec3::ONE, Vec3::ZERO);
            entry = self.nodes[(entry + octant) as usize];
        }
        Some(entry & !LEAF)
    }

    pub(crate) fn build_cdfs(&mut self, all: bool) {
        let patches = self.patch_count();
        let mix = self.settings.uniform_mix;
        let rows = self.cdf.chunks_exact_mut(patches).zip(self.q.chunks_exact(patches)).zip(&mut self.irradiance);
        for (((cdf, q), sh), (visits, built)) in rows.zip(self.leaf_visits.iter().zip(&mut self.visits_at_build)) {
            let visits = visits.load(Ordering::Relaxed);
            if all || visits != *built {
                build_cdf(cdf, mix, |k| atomic_f32::load(&q[k]));
                *sh = irradiance_sh::project(q.iter().map(atomic_f32::load), &self.patch_basis);
                *built = visits;
            }
        }
    }

    /// The bytes one split adds: seven new leaves and eight nodes.
    pub(crate) fn split_bytes(&self) -> usize {
        7 * self.settings.bytes_per_leaf() + 8 * BYTES_PER_NODE
    }

    /// The leaves the next rebuild splits, as (visits, node) pairs, most-updated first:
    /// those that took enough updates, as many as the budget holds.
    fn busy_leaves(&self) -> Vec<(u32, u32)> {
        let patches = self.patch_count();
        let threshold = (self.settings.split_updates_per_patch as f64 * patches as f64) as u64;
        let mut busy: Vec<(u32, u32)> = Vec::new();
        for (node, &entry) in self.nodes.iter().enumerate() {
            if entry & LEAF != 0 {
                let visits = self.leaf_visits[(entry & !LEAF) as usize].load(Ordering::Relaxed);
                if visits as u64 >= threshold {
                    busy.push((visits, node as u32));
                }
            }
        }
        if busy.is_empty() {
            return busy;
        }
        busy.sort_unstable_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
        let room = self.settings.budget_bytes.saturating_sub(self.memory_bytes()) / self.split_bytes();
        busy.truncate(room);
        busy
    }

    /// Whether the next [`rebuild_sampling`](Guide::rebuild_sampling) splits a leaf
    /// (given the visit counts as they stand). A tracer that learns elsewhere (a GPU)
    /// asks this between passes and brings the tables home only when it does.
    pub fn splits_pending(&self) -> bool {
        !self.busy_leaves().is_empty()
    }

    /// The most leaves and tree nodes splitting can reach within the budget: what a
    /// copy of the tables elsewhere must hold room for.
    pub fn capacity(&self) -> (usize, usize) {
        let splits = self.settings.budget_bytes.saturating_sub(self.memory_bytes()) / self.split_bytes();
        (self.leaf_count() + 7 * splits, self.node_count() + 8 * splits)
    }

    /// Splits the leaves that took enough updates, most-updated first, while the budget
    /// holds the seven new leaves and eight nodes each split adds.
    fn split_busy_leaves(&mut self) {
        let patches = self.patch_count();
        let busy = self.busy_leaves();
        if busy.is_empty() {
            return;
        }
        let new_leaves = 7 * busy.len();
        self.nodes.reserve_exact(8 * busy.len());
        self.q.reserve_exact(new_leaves * patches);
        self.patch_visits.reserve_exact(new_leaves * patches);
        self.patch_weights.reserve_exact(new_leaves * patches);
        self.cdf.reserve_exact(new_leaves * patches);
        self.leaf_visits.reserve_exact(new_leaves);
        self.visits_at_build.reserve_exact(new_leaves);
        self.irradiance.reserve_exact(new_leaves);
        for &(_, node) in &busy {
            self.split_leaf_at(node);
        }
    }

    /// Splits the leaf at tree entry `node` into eight: the first child keeps the
    /// leaf's table, seven copies follow, and each holds an eighth of its visits and
    /// weights. The caller checks the budget.
    pub(crate) fn split_leaf_at(&mut self, node: u32) {
        let patches = self.patch_count();
        let parent = self.nodes[node as usize] & !LEAF;
        let first_child = self.nodes.len() as u32;
        self.nodes[node as usize] = first_child;
        self.nodes.push(LEAF | parent);
        let share = |v: u32| v / 8;
        let row = parent as usize * patches..(parent as usize + 1) * patches;
        for slot in &self.patch_visits[row.clone()] {
            slot.store(share(slot.load(Ordering::Relaxed)), Ordering::Relaxed);
        }
        for slot in &self.patch_weights[row.clone()] {
            slot.store((atomic_f32::load(slot) / 8.0).to_bits(), Ordering::Relaxed);
        }
        let leaf_visits = share(self.leaf_visits[parent as usize].load(Ordering::Relaxed));
        self.leaf_visits[parent as usize].store(leaf_visits, Ordering::Relaxed);
        for _ in 0..7 {
            let leaf = self.leaf_visits.len() as u32;
            self.nodes.push(LEAF | leaf);
            for k in row.clone() {
                self.q.push(AtomicU32::new(self.q[k].load(Ordering::Relaxed)));
                self.patch_visits.push(AtomicU32::new(self.patch_visits[k].load(Ordering::Relaxed)));
                self.patch_weights.push(atomic_f32::new(atomic_f32::load(&self.patch_weights[k])));
                self.cdf.push(self.cdf[k]);
            }
            self.leaf_visits.push(AtomicU32::new(leaf_visits));
            self.visits_at_build.push(u32::MAX);
            self.irradiance.push(self.irradiance[parent as usize]);
        }
        self.visits_at_build[parent as usize] = u32::MAX;
    }
}

impl Clone for IrradianceVolume {
    fn clone(&self) -> Self {
        let mut copy = Self::assemble(self.low, self.high, self.settings, self.grid, self.state());
        // Leaves that changed since their last build stay due for one.
        copy.visits_at_build.clone_from(&self.visits_at_build);
        copy
    }
}

impl IrradianceVolume {
    /// Learns `target` for `direction`, the update weighing `weight` (1 unweighted).
    fn update_weighted(&self, region: VolumeRegion, direction: Vec3, target: f32, weight: f32) -> UpdateOutcome {
        let target = match accept_target(target, &self.rejected_negative, &self.rejected_non_finite) {
            Ok(t) => t,
            Err(rejected) => return rejected,
        };
        let Some(patch) = self.settings.layout.patch_of(direction) else {
            return UpdateOutcome::OutsideDomain;
        };
        let leaf = region.leaf as usize;
        let index = leaf * self.patch_count() + patch;
        let slots = EntrySlots {
            q: &self.q[index],
            visits: &self.patch_visits[index],
            weights: &self.patch_weights[index],
            region_visits: &self.leaf_visits[leaf],
        };
        learn_entry(slots, target, weight, &self.settings.update_rule, self.epoch, self.settings.q_floor);
        UpdateOutcome::Accepted
    }
}

/// One leaf's row: its sphere of patches in world axes, seen from the region's normal.
struct LeafRow<'a> {
    volume: &'a IrradianceVolume,
    region: VolumeRegion,
}

impl TableRow for LeafRow<'_> {
    fn q(&self) -> &[AtomicU32] {
        let (leaf, patches) = (self.region.leaf as usize, self.volume.patch_count());
        &self.volume.q[leaf * patches..(leaf + 1) * patches]
    }

    fn entry_solid_angle(&self) -> f64 {
        self.volume.settings.layout.patch_solid_angle() as f64
    }

    fn entry_of(&self, wi: Vec3) -> Option<usize> {
        self.volume.settings.layout.patch_of(wi)
    }

    fn center(&self, k: usize) -> Vec3 {
        self.volume.patch_centers[k]
    }

    fn center_cos(&self, k: usize) -> f32 {
        self.volume.patch_centers[k].dot(self.region.normal).max(0.0)
    }

    fn direction_in_entry(&self, k: usize, u: Vec2) -> Vec3 {
        self.volume.settings.layout.direction_in_patch(k, u)
    }

    fn lambertian_integral(&self, albedo: f32) -> f64 {
        let irradiance = &self.volume.irradiance[self.region.leaf as usize];
        albedo as f64 * irradiance_sh::cosine_integral(irradiance, self.region.normal) as f64
    }
}

impl Guide for IrradianceVolume {
    type Records = ();
    type Region = VolumeRegion;
    type Distribution<'a> = VolumeDistribution<'a>;

    fn locate(&self, position: Vec3, normal: Vec3) -> Option<VolumeRegion> {
        let normal = normal.try_normalize()?;
        Some(VolumeRegion { leaf: self.leaf_at(position)?, normal })
    }

    fn distribution(&self, region: VolumeRegion) -> VolumeDistribution<'_> {
        let patches = self.patch_count();
        let start = region.leaf as usize * patches;
        VolumeDistribution {
            cdf: &self.cdf[start..start + patches],
            layout: self.settings.layout,
            normal: region.normal,
        }
    }

    fn update(&self, region: VolumeRegion, direction: Vec3, target: f32) -> UpdateOutcome {
        self.update_weighted(region, direction, target, 1.0)
    }

    /// Weighs the update by the density the direction was drawn with (see
    /// [`importance_weight`]): each patch learns its mean over its solid angle.
    fn update_sampled(&self, region: VolumeRegion, direction: Vec3, target: f32, pdf: f32) -> UpdateOutcome {
        match importance_weight(0.25 / core::f32::consts::PI, pdf) {
            Some(weight) => self.update_weighted(region, direction, target, weight),
            None => UpdateOutcome::OutsideDomain,
        }
    }

    /// By the settings' [`IntegralEstimator`](crate::IntegralEstimator), as for every
    /// table structure; a Lambertian BSDF's closed form here is albedo × the leaf's
    /// spherical-harmonic cosine integral about the region's normal (Q as of the last
    /// rebuild; nine terms).
    fn estimate_integral<S: ScatteringFunction + ?Sized>(
        &self,
        region: VolumeRegion,
        wo: Vec3,
        bsdf: &S,
        u: Vec2,
    ) -> f32 {
        let row = LeafRow { volume: self, region };
        estimate_row_integral(self.settings.update_rule.integral, &row, bsdf, wo, u)
    }

    fn update_rule(&self) -> crate::update_rule::UpdateRule {
        self.settings.update_rule
    }

    fn rebuild_sampling(&mut self) {
        self.split_busy_leaves();
        self.build_cdfs(false);
        self.epoch = self.epoch.saturating_add(1);
    }

    fn stats(&self) -> GuideStats {
        let counters = TableCounters {
            visits: &self.patch_visits,
            rejected_non_finite: self.rejected_non_finite.load(Ordering::Relaxed) as u64,
            rejected_negative: self.rejected_negative.load(Ordering::Relaxed) as u64,
        };
        GuideStats::of_tables(self.leaf_count(), self.patch_count(), self.memory_bytes(), self.epoch, counters)
    }

    fn validate(&self) -> Result<(), Error> {
        super::serialize::check_tree(&self.nodes, self.grid.cell_count(), self.leaf_count())?;
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
        IrradianceVolume::merge(self, other)
    }
}

#[cfg(test)]
mod tests;
