//! [`SpatialDirectionalTree`]: Q(x, ω) in a binary tree over space whose leaves each hold
//! a quadtree over directions, refined together where paths land (Müller et al. 2017's
//! SD-tree, learning the seed's targets).

use alloc::vec::Vec;
use core::f32::consts::PI;
use core::sync::atomic::{AtomicU32, Ordering};

use glam::{Vec2, Vec3};

use super::axis::{rotated_cells, LeafCounts, ROTATED_NODES, ROTATED_SIDE};
use super::distribution::TreeDistribution;
use super::quadtree::{self, EpochBlend, QuadNode, RefitRule, NODE_BYTES};
use super::records::TreeRecords;
use super::settings::SpatialDirectionalTreeSettings;
use super::spatial::{descend_to_leaf, split_leaf, unit_position, Parent, SpatialNode, LEAF, SPATIAL_NODE_BYTES};
use super::square::{axis_square, SQUARE_TO_SOLID_ANGLE};
use super::top_grid::{TopGrid, TOP_GRID_BYTES_PER_NODE};
use crate::atomic_f32;
use crate::distribution::MIN_SAMPLED_COS_THETA;
use crate::error::Error;
use crate::frame::Frame;
use crate::guide::{Guide, GuideStats};
use crate::scattering::ScatteringFunction;
use crate::update_rule::{classify_target, LearningRate, UpdateOutcome, UpdateRule};

/// A located region: a spatial leaf, and the surface normal its distribution folds onto.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeRegion {
    /// Index of the spatial leaf.
    pub leaf: u32,
    /// Unit normal facing the side the path arrives from.
    pub normal: Vec3,
    /// Whether the point lies in the upper half of the leaf along the axis the leaf
    /// would split next: records count per half, so the two leaves of a split can each
    /// build their square around their own normals' axis.
    pub upper_half: bool,
}

/// One spatial leaf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SpatialLeaf {
    /// Root of its directional quadtree in the arena.
    pub(crate) root: u32,
    /// ∫ L dω over the sphere the quadtree stands for (radiance × sr).
    pub(crate) flux: f32,
    /// Records learned from in all completed epochs (halved at each spatial split).
    pub(crate) weight: f64,
    /// Where the leaf hangs in the spatial tree.
    pub(crate) parent: Parent,
    /// Its box's size along x, y, z, scene units.
    pub(crate) extent: Vec3,
    /// Splits from the root.
    pub(crate) depth: u32,
    /// The world axis (0, 1, 2 for x, y, z) its quadtree's square is built around: the
    /// axis most of its records' normals lie along, so that the hemisphere of such a
    /// normal is exactly one half of the square.
    pub(crate) axis: u32,
}

/// Bytes one spatial leaf costs (with its epoch's counts).
pub(crate) const LEAF_BYTES: usize = core::mem::size_of::<SpatialLeaf>() + core::mem::size_of::<LeafCounts>();

/// Q(x, ω) as a spatial binary tree whose every leaf holds a directional quadtree over
/// the sphere (Lambert's equal-area square), both refined between epochs where the
/// records say so, within a byte budget.
///
/// Learning is by records: [`update_sampled`](Guide::update_sampled) adds target/pdf to
/// the building sum of the quadtree cell the direction falls in (one lock-free add; the
/// sampling side is read-only during a pass), or [`record`](Guide::record) appends it to
/// a thread's own [`TreeRecords`](crate::TreeRecords), added by [`splat`](Guide::splat)
/// after the pass with no write shared between threads. Each cell estimates the flux
/// ∫ L dω over its solid angle whatever density drew its directions (with the settings'
/// `second_moment`, the default, target²/pdf and ∫ L² dω, whose root gives the cell
/// its share). Between passes
/// [`rebuild_sampling`](Guide::rebuild_sampling) blends each leaf's new estimate with its
/// old one by the learning rate, splits directional cells holding more than
/// `flux_fraction` of their leaf's flux, merges those holding less, and splits spatial
/// leaves that took more than c·√R of the epoch's R records.
///
/// ```
/// use glam::{Vec2, Vec3};
/// use guiding_core::{DirectionalDistribution, Guide, Pcg32, SpatialDirectionalTree, SpatialDirectionalTreeSettings};
/// let settings = SpatialDirectionalTreeSettings::default();
/// let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
/// let region = tree.locate(Vec3::new(0.0, -1.0, 0.0), Vec3::Y).unwrap();
/// let light = Vec3::new(0.6, 0.8, 0.0);
/// let mut rng = Pcg32::new(1, 1);
/// // Each epoch refines where the last one found flux, then learns inside the new cells.
/// for _epoch in 0..4 {
///     for _ in 0..20_000 {
///         let s = tree.sample(region, rng.next_vec2());
///         let target = if s.direction.dot(light) > 0.99 { 50.0 } else { 0.1 };
///         tree.update_sampled(region, s.direction, target, s.pdf);
///     }
///     tree.rebuild_sampling();
/// }
/// let d = tree.distribution(region);
/// assert!(d.pdf(light) > 10.0 * d.pdf(Vec3::new(-0.6, 0.8, 0.0)));
/// ```
pub struct SpatialDirectionalTree {
    pub(crate) settings: SpatialDirectionalTreeSettings,
    pub(crate) low: Vec3,
    pub(crate) extent: Vec3,
    pub(crate) inverse_extent: Vec3,
    /// The spatial trees' roots (node index, or `LEAF | leaf`): one, or one per world
    /// axis ([`SpatialDirectionalTreeSettings::trees_per_axis`]).
    pub(crate) spatial_roots: Vec<u32>,
    pub(crate) spatial: Vec<SpatialNode>,
    pub(crate) leaves: Vec<SpatialLeaf>,
    /// What each leaf's records of the current epoch were: per half, how many, and
    /// along which axis their normals lay.
    pub(crate) leaf_counts: Vec<LeafCounts>,
    pub(crate) quad: Vec<QuadNode>,
    /// Building sums Σ target/pdf, four per quadtree node (f32 bits).
    pub(crate) sums: Vec<AtomicU32>,
    /// Per quadtree node, its cells' probabilities under the cosine product (derived
    /// from `quad` by [`refresh_derived`](Self::refresh_derived); never serialized).
    pub(crate) cosine: Vec<[f32; 4]>,
    /// Where locates start (derived from `spatial` by
    /// [`refresh_derived`](Self::refresh_derived); never serialized).
    pub(crate) top: TopGrid,
    pub(crate) epoch: u32,
    /// Records of the completed epochs.
    pub(crate) accepted_before: u64,
    pub(crate) rejected_non_finite: AtomicU32,
    pub(crate) rejected_negative: AtomicU32,
}

impl SpatialDirectionalTree {
    /// A tree over the box `low`–`high` (scene units): one leaf, one uniform quadtree.
    pub fn new(low: Vec3, high: Vec3, settings: SpatialDirectionalTreeSettings) -> Result<Self, Error> {
        settings.validate()?;
        // The extent too: a box from −3e38 to 3e38 has corners in f32 but no size.
        let padded = (high - low) * (1.0 + 2e-6);
        if !(low.is_finite() && high.is_finite() && padded.is_finite()) {
            let value = padded.max_element() as f64;
            return Err(Error::InvalidSetting { name: "bounds", value, requirement: "finite, with a finite extent" });
        }
        let trees = settings.spatial_tree_count();
        let needed = bytes_for(0, trees, trees);
        if settings.budget_bytes < needed {
            return Err(Error::BudgetTooSmall { budget_bytes: settings.budget_bytes, needed_bytes: needed });
        }
        // A flat box still gets a positive extent: its points all fall in one layer.
        let size = (high - low).max(Vec3::ZERO);
        let extent = size.max(Vec3::splat(size.max_element().max(1.0) * 1e-6));
        // One leaf per spatial tree, its square around its tree's axis (z for a single
        // tree, until its records say otherwise).
        let leaves: Vec<SpatialLeaf> = (0..trees as u32)
            .map(|index| SpatialLeaf {
                root: index,
                flux: 0.0,
                weight: 0.0,
                parent: Parent::Root { tree: index },
                extent,
                depth: 0,
                axis: if settings.trees_per_axis { index } else { 2 },
            })
            .collect();
        let mut tree = Self {
            settings,
            low: low - extent * 1e-6,
            extent: extent * (1.0 + 2e-6),
            inverse_extent: (extent * (1.0 + 2e-6)).recip(),
            spatial_roots: (0..trees as u32).map(|leaf| LEAF | leaf).collect(),
            spatial: Vec::new(),
            leaf_counts: leaves.iter().map(|_| LeafCounts::default()).collect(),
            leaves,
            quad: alloc::vec![QuadNode::UNIFORM; trees],
            sums: (0..4 * trees).map(|_| atomic_f32::new(0.0)).collect(),
            cosine: Vec::new(),
            top: TopGrid::default(),
            epoch: 0,
            accepted_before: 0,
            rejected_non_finite: AtomicU32::new(0),
            rejected_negative: AtomicU32::new(0),
        };
        tree.refresh_derived();
        Ok(tree)
    }

    /// Forgets everything learned: one leaf per spatial tree over the same box, each with
    /// a uniform quadtree, no records, epoch 0 (as [`new`](Self::new) made it, to the
    /// rounding of the box).
    pub fn reset(&mut self) {
        let extent = self.extent / (1.0 + 2e-6);
        let low = self.low + extent * 1e-6;
        if let Ok(fresh) = Self::new(low, low + extent, self.settings) {
            *self = fresh;
        }
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &SpatialDirectionalTreeSettings {
        &self.settings
    }

    /// Spatial leaves.
    pub fn leaf_count(&self) -> usize {
        self.leaves.len()
    }

    /// Directional quadtree nodes over all leaves.
    pub fn directional_node_count(&self) -> usize {
        self.quad.len()
    }

    /// The deepest directional cell of `leaf`'s quadtree (1 for a root alone).
    pub fn directional_depth(&self, leaf: u32) -> u32 {
        fn depth(nodes: &[QuadNode], node: u32) -> u32 {
            1 + nodes[node as usize].child.iter().filter(|&&c| c != 0).map(|&c| depth(nodes, c)).max().unwrap_or(0)
        }
        self.leaves.get(leaf as usize).map_or(0, |l| depth(&self.quad, l.root))
    }

    /// The world axis (0, 1, 2 for x, y, z) `leaf`'s directional square is built around.
    pub fn leaf_axis(&self, leaf: u32) -> Option<u32> {
        self.leaves.get(leaf as usize).map(|l| l.axis)
    }

    /// ∫ L dω over the sphere at `leaf` as learned (radiance × sr).
    pub fn leaf_flux(&self, leaf: u32) -> f32 {
        self.leaves.get(leaf as usize).map_or(0.0, |l| l.flux)
    }

    /// Q(region, ω): the radiance the leaf has learned to arrive from `direction` (its
    /// root mean square with the settings' `second_moment`).
    pub fn q(&self, region: TreeRegion, direction: Vec3) -> f32 {
        let Some(leaf) = self.leaves.get(region.leaf as usize) else { return 0.0 };
        let p = axis_square(direction, leaf.axis);
        leaf.flux * quadtree::square_density(&self.quad, leaf.root, p) / SQUARE_TO_SOLID_ANGLE
    }

    /// Replaces `region`'s quadtree by a full tree of `depth` levels (1..=6) whose
    /// 4^depth cells (row-major over the leaf's square, whose polar axis is
    /// [`leaf_axis`](Self::leaf_axis), u fastest) hold the flux `values`
    /// (non-finite or negative values count as 0); the building sums of the epoch are
    /// cleared. For tests and tools that set a known distribution.
    pub fn set_leaf_cells(&mut self, region: TreeRegion, depth: u32, values: &[f32]) {
        let depth = depth.clamp(1, 6);
        let side = 1usize << depth;
        if region.leaf as usize >= self.leaves.len() {
            return;
        }
        let value = |i: usize| values.get(i % values.len().max(1)).copied().filter(|v| v.is_finite() && *v > 0.0);
        let cells: Vec<f64> = (0..side * side).map(|i| value(i).unwrap_or(0.0) as f64).collect();
        // Rebuild the arena with every other leaf's tree copied and this one replaced.
        let mut out = Vec::with_capacity(self.quad.len());
        let mut roots = Vec::with_capacity(self.leaves.len());
        for (index, other) in self.leaves.iter().enumerate() {
            if index == region.leaf as usize {
                roots.push(quadtree::full_tree(&cells, side, 0, 0, side, &mut out).0);
            } else {
                roots.push(quadtree::copy_tree(&self.quad, other.root, 0, &mut out));
            }
        }
        for (l, root) in self.leaves.iter_mut().zip(roots) {
            l.root = root;
        }
        let total: f64 = cells.iter().sum();
        self.leaves[region.leaf as usize].flux = total.min(f32::MAX as f64) as f32 / (side * side) as f32;
        self.quad = out;
        self.sums = (0..self.quad.len() * 4).map(|_| atomic_f32::new(0.0)).collect();
        self.leaf_counts = (0..self.leaves.len()).map(|_| LeafCounts::default()).collect();
        self.refresh_derived();
    }

    /// Recomputes what is derived from the trees after every change to them: the cosine
    /// product's cell probabilities (none where the settings leave the product off) and
    /// the top grid locates start from.
    pub(crate) fn refresh_derived(&mut self) {
        self.top = TopGrid::build(&self.spatial, &self.spatial_roots);
        self.cosine = if self.settings.cosine_product {
            super::cosine::cosine_probabilities(&self.quad, self.leaves.iter().map(|leaf| leaf.root))
        } else {
            Vec::new()
        };
    }

    /// Bytes held by the trees and their building statistics.
    pub fn memory_bytes(&self) -> usize {
        bytes_for(self.spatial.len(), self.leaves.len(), self.quad.len())
    }

    fn alpha(&self, previous_weight: f64, records: u32) -> f64 {
        if records == 0 {
            return 0.0;
        }
        match self.settings.update_rule.learning_rate {
            LearningRate::SimpleAverage | LearningRate::RegionVisits => {
                records as f64 / (previous_weight + records as f64)
            }
            LearningRate::Exponential { alpha } => alpha as f64,
            LearningRate::Global { exponent } => libm::pow(1.0 + self.epoch as f64, -(exponent as f64)),
        }
    }

    /// What a record of `target` along unit `direction` (drawn with density `pdf`) in
    /// `region` adds to its cell: target/pdf (target²/pdf under the second moment); or the
    /// outcome that leaves it out (bad targets counted).
    #[inline]
    pub(super) fn checked_weight(
        &self,
        region: TreeRegion,
        direction: Vec3,
        target: f32,
        pdf: f32,
    ) -> Result<f32, UpdateOutcome> {
        let target = classify_target(target).inspect_err(|outcome| {
            let counter = match outcome {
                UpdateOutcome::RejectedNegative => &self.rejected_negative,
                _ => &self.rejected_non_finite,
            };
            atomic_f32::increment_saturating(counter);
        })?;
        // A NaN or infinite component makes the length NaN or infinite: no unit then.
        let unit = (direction.length_squared() - 1.0).abs() < 1e-3;
        if region.leaf as usize >= self.leaves.len() || !(unit && pdf.is_finite() && pdf > 0.0) {
            return Err(UpdateOutcome::OutsideDomain);
        }
        let moment = if self.settings.second_moment { target * target } else { target };
        Ok((moment / pdf).min(f32::MAX))
    }

    /// [`Guide::update_sampled`] for [`Guide::record`]'s rare leaf that a record cannot
    /// name. Out of line, and given the direction's components: a direction passed on by
    /// reference would keep every push's direction in memory, and the push's checks would
    /// wait on loads across the two stores that put it there (a store-forwarding stall).
    #[cold]
    #[inline(never)]
    fn update_in_place(&self, region: TreeRegion, x: f32, y: f32, z: f32, target: f32, pdf: f32) -> UpdateOutcome {
        self.update_sampled(region, Vec3::new(x, y, z), target, pdf)
    }

    /// The cell of leaf `leaf` (which exists) that `direction` falls in.
    #[inline]
    pub(super) fn leaf_cell_of(&self, leaf: usize, direction: Vec3) -> usize {
        let SpatialLeaf { root, axis, .. } = self.leaves[leaf];
        quadtree::leaf_cell(&self.quad, root, axis_square(direction, axis))
    }

    /// Splits every leaf whose records (over all epochs, halved at each split) pass the
    /// threshold, heaviest first, as long as the budget holds; halves keep splitting
    /// while their share does. A leaf whose epoch's normals are mixed (the settings'
    /// `mixed_normal_share`) splits once, whatever its count.
    fn split_busy_leaves(&mut self, threshold: f64) {
        let (share, least) = (self.settings.mixed_normal_share as f64, self.settings.min_split_records);
        let mut queue: Vec<(u32, f64)> = self
            .leaves
            .iter()
            .zip(&self.leaf_counts)
            .enumerate()
            .filter_map(|(index, (leaf, counts))| {
                if leaf.weight > threshold {
                    Some((index as u32, leaf.weight))
                } else {
                    // Queued at the threshold itself: its halves do not split again now.
                    counts.mixed(share, least).then_some((index as u32, threshold))
                }
            })
            .collect();
        queue.sort_by(|a, b| b.1.total_cmp(&a.1));
        let (mut next, mut orphaned) = (0, false);
        while next < queue.len() {
            let (leaf, count) = queue[next];
            next += 1;
            let old = self.leaves[leaf as usize];
            if old.depth >= self.settings.max_spatial_depth {
                continue;
            }
            // Each half picks the axis its records' normals lie along (the counts were
            // kept per half for this); a half that picks a new one gets its tree turned.
            let counts = core::mem::take(&mut self.leaf_counts[leaf as usize]);
            let axes = [0, 1].map(|h| self.axis_for(&counts, &[h], old.axis));
            let tree_nodes = quadtree::node_count(&self.quad, old.root);
            let added = (axes[0] != old.axis) as usize * ROTATED_NODES
                + if axes[1] != old.axis { ROTATED_NODES } else { tree_nodes };
            let grown = bytes_for(self.spatial.len() + 1, self.leaves.len() + 1, self.quad.len() + added);
            if grown > self.settings.budget_bytes {
                continue;
            }
            let axis = old.extent.max_position() as u32;
            let new_leaf = self.leaves.len() as u32;
            let node = split_leaf(&mut self.spatial, &mut self.spatial_roots, old.parent, leaf, new_leaf, axis);
            let mut extent = old.extent;
            extent[axis as usize] *= 0.5;
            let half = SpatialLeaf { weight: old.weight * 0.5, extent, depth: old.depth + 1, ..old };
            let high_root = if axes[1] != old.axis {
                self.turned_tree(old.root, old.axis, axes[1])
            } else {
                // Copied aside and appended: the arena is not cloned for every split.
                let mut copy = Vec::with_capacity(tree_nodes);
                let root = quadtree::copy_tree(&self.quad, old.root, self.quad.len(), &mut copy);
                self.quad.extend(copy);
                root
            };
            let low_root = if axes[0] != old.axis {
                orphaned = true;
                self.turned_tree(old.root, old.axis, axes[0])
            } else {
                old.root
            };
            let side = |side| Parent::Node { node, side };
            self.leaves[leaf as usize] = SpatialLeaf { root: low_root, parent: side(0), axis: axes[0], ..half };
            self.leaves.push(SpatialLeaf { root: high_root, parent: side(1), axis: axes[1], ..half });
            self.leaf_counts.push(LeafCounts::default());
            if count * 0.5 > threshold {
                queue.push((leaf, count * 0.5));
                queue.push((new_leaf, count * 0.5));
            }
        }
        if orphaned {
            // A low half turned away from its tree left that tree unreachable.
            let mut out = Vec::with_capacity(self.quad.len());
            for leaf in &mut self.leaves {
                leaf.root = quadtree::copy_tree(&self.quad, leaf.root, 0, &mut out);
            }
            self.quad = out;
        }
    }

    /// The axis a leaf built around `axis` should turn its square to, by its records in
    /// `halves`: the one most of their normals lie along, if any; a leaf of a tree per
    /// axis keeps its tree's.
    fn axis_for(&self, counts: &LeafCounts, halves: &[usize], axis: u32) -> u32 {
        if self.settings.trees_per_axis {
            return axis;
        }
        counts.majority_axis(halves).unwrap_or(axis)
    }

    /// Appends the tree at `root` (built around `old_axis`) turned to `axis`; returns
    /// the new root.
    fn turned_tree(&mut self, root: u32, old_axis: u32, axis: u32) -> u32 {
        let cells = rotated_cells(&self.quad, root, old_axis, axis);
        quadtree::full_tree(&cells, ROTATED_SIDE, 0, 0, ROTATED_SIDE, &mut self.quad).0
    }
}

/// Bytes of a tree with these node and leaf counts (each inner node paying for its share
/// of the top grid).
pub(crate) fn bytes_for(spatial_nodes: usize, leaves: usize, quad_nodes: usize) -> usize {
    core::mem::size_of::<SpatialDirectionalTree>()
        + spatial_nodes * (SPATIAL_NODE_BYTES + TOP_GRID_BYTES_PER_NODE)
        + leaves * LEAF_BYTES
        + quad_nodes * NODE_BYTES
}

impl Clone for SpatialDirectionalTree {
    fn clone(&self) -> Self {
        let copy = |cells: &[AtomicU32]| cells.iter().map(|c| AtomicU32::new(c.load(Ordering::Relaxed))).collect();
        Self {
            settings: self.settings,
            low: self.low,
            extent: self.extent,
            inverse_extent: self.inverse_extent,
            spatial_roots: self.spatial_roots.clone(),
            spatial: self.spatial.clone(),
            leaves: self.leaves.clone(),
            leaf_counts: self.leaf_counts.clone(),
            quad: self.quad.clone(),
            sums: copy(&self.sums),
            cosine: self.cosine.clone(),
            top: self.top.clone(),
            epoch: self.epoch,
            accepted_before: self.accepted_before,
            rejected_non_finite: AtomicU32::new(self.rejected_non_finite.load(Ordering::Relaxed)),
            rejected_negative: AtomicU32::new(self.rejected_negative.load(Ordering::Relaxed)),
        }
    }
}

impl Guide for SpatialDirectionalTree {
    type Region = TreeRegion;
    type Distribution<'a> = TreeDistribution<'a>;

    fn locate(&self, position: Vec3, normal: Vec3) -> Option<TreeRegion> {
        if !normal.is_finite() {
            return None;
        }
        let tree = if self.settings.trees_per_axis { normal.abs().max_position() } else { 0 };
        let root = *self.spatial_roots.get(tree)?;
        let p = unit_position(self.low, self.inverse_extent, position)?;
        let (start, p) = self.top.start(tree, root, p);
        let (leaf, local) = descend_to_leaf(&self.spatial, start, p);
        let split_axis = self.leaves.get(leaf as usize)?.extent.max_position();
        Some(TreeRegion { leaf, normal, upper_half: local[split_axis] >= 0.5 })
    }

    fn distribution(&self, region: TreeRegion) -> TreeDistribution<'_> {
        let (root, axis) = self.leaves.get(region.leaf as usize).map_or((0, 2), |l| (l.root, l.axis));
        let settings = &self.settings;
        let cosine = settings.cosine_product.then_some(self.cosine.as_slice());
        TreeDistribution::new(
            &self.quad,
            cosine,
            root,
            axis,
            region.normal,
            settings.uniform_mix,
            settings.fold_to_hemisphere,
        )
    }

    /// Records `target` as if `direction` had been drawn uniformly over the sphere
    /// (pdf 1/4π); renderers should call [`update_sampled`](Guide::update_sampled).
    fn update(&self, region: TreeRegion, direction: Vec3, target: f32) -> UpdateOutcome {
        self.update_sampled(region, direction, target, 1.0 / SQUARE_TO_SOLID_ANGLE)
    }

    fn update_sampled(&self, region: TreeRegion, direction: Vec3, target: f32, pdf: f32) -> UpdateOutcome {
        let weight = match self.checked_weight(region, direction, target, pdf) {
            Ok(weight) => weight,
            Err(outcome) => return outcome,
        };
        let cell = self.leaf_cell_of(region.leaf as usize, direction);
        quadtree::add_record(&self.sums, cell, weight);
        self.leaf_counts[region.leaf as usize].add(region.upper_half as usize, region.normal);
        UpdateOutcome::Accepted
    }

    type Records = TreeRecords;

    /// Appends the record to the thread's `records`: the direction and the weight,
    /// nothing written that other threads read (its square point is found later, see
    /// [`TreeRecords`]). A leaf beyond what a record can name (never within a realistic
    /// budget) learns in place.
    #[inline]
    fn record(
        &self,
        records: &mut TreeRecords,
        region: TreeRegion,
        direction: Vec3,
        target: f32,
        pdf: f32,
    ) -> UpdateOutcome {
        if !TreeRecords::can_name(region.leaf) {
            return self.update_in_place(region, direction.x, direction.y, direction.z, target, pdf);
        }
        match self.checked_weight(region, direction, target, pdf) {
            Ok(weight) => {
                records.push(self.epoch, region, direction, weight);
                UpdateOutcome::Accepted
            }
            Err(outcome) => outcome,
        }
    }

    fn prepare_splat(&self, records: &mut TreeRecords) {
        self.map_records(records);
    }

    fn splat(&mut self, records: &mut TreeRecords) -> usize {
        self.splat_records(records)
    }

    fn estimate_integral<S: ScatteringFunction + ?Sized>(
        &self,
        region: TreeRegion,
        wo: Vec3,
        bsdf: &S,
        u: Vec2,
    ) -> f32 {
        // One direction from the BSDF (cosine-distributed for a Lambertian one), weighted
        // by Q there: unbiased for the tree's piecewise-constant Q at one lookup.
        let estimate = if let Some(albedo) = bsdf.lambertian_albedo() {
            let r = libm::sqrtf(u.x);
            let phi = 2.0 * PI * u.y;
            let z = libm::sqrtf((1.0 - u.x).max(0.0));
            let wi = Frame::from_normal(region.normal).to_world(Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z));
            self.q(region, wi) * albedo
        } else if let Some(s) = bsdf.can_sample().then(|| bsdf.sample_cos(wo, u)).flatten() {
            self.q(region, s.wi) * s.weight
        } else {
            let z = u.x.max(MIN_SAMPLED_COS_THETA);
            let r = libm::sqrtf((1.0 - z * z).max(0.0));
            let phi = 2.0 * PI * u.y;
            let wi = Frame::from_normal(region.normal).to_world(Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z));
            self.q(region, wi) * bsdf.eval_cos(wi, wo) * 2.0 * PI
        };
        if estimate.is_finite() {
            estimate.max(0.0)
        } else {
            0.0
        }
    }

    fn rebuild_sampling(&mut self) {
        let records: Vec<u32> = self.leaf_counts.iter().map(LeafCounts::records).collect();
        let epoch_records: u64 = records.iter().map(|&n| n as u64).sum();
        self.epoch = self.epoch.saturating_add(1);
        if epoch_records == 0 {
            return;
        }
        // Directional refit of every leaf into a fresh arena, capped so that every leaf
        // still to come keeps room for its root.
        let fixed = bytes_for(self.spatial.len(), self.leaves.len(), 0);
        let node_budget = self.settings.budget_bytes.saturating_sub(fixed) / NODE_BYTES;
        let mut out = Vec::with_capacity(self.quad.len());
        let (mut scratch, mut unrotated) = (Vec::new(), Vec::new());
        let leaf_count = self.leaves.len();
        for (index, &n) in records.iter().enumerate() {
            let leaf = self.leaves[index];
            let blend = EpochBlend {
                previous_flux: leaf.flux as f64,
                sum_scale: if n > 0 { 1.0 / n as f64 } else { 0.0 },
                alpha: self.alpha(leaf.weight, n),
                second_moment: self.settings.second_moment,
            };
            let rule = RefitRule {
                flux_fraction: self.settings.flux_fraction as f64,
                max_depth: self.settings.max_directional_depth,
                node_cap: node_budget.saturating_sub(leaf_count - index - 1).max(out.len() + 1),
            };
            // A leaf whose records' normals mostly lie along another axis turns its square
            // to it (where the budget has room), so their hemispheres are halves of it.
            let best = self.axis_for(&self.leaf_counts[index], &[0, 1], leaf.axis);
            let turns = best != leaf.axis && out.len() + ROTATED_NODES <= rule.node_cap;
            let (root, flux) = if turns {
                unrotated.clear();
                let (root, flux) =
                    quadtree::refit(&self.quad, &self.sums, leaf.root, blend, rule, &mut scratch, &mut unrotated);
                let cells = rotated_cells(&unrotated, root, leaf.axis, best);
                (quadtree::full_tree(&cells, ROTATED_SIDE, 0, 0, ROTATED_SIDE, &mut out).0, flux)
            } else {
                quadtree::refit(&self.quad, &self.sums, leaf.root, blend, rule, &mut scratch, &mut out)
            };
            let leaf = &mut self.leaves[index];
            leaf.root = root;
            leaf.flux = flux.min(f32::MAX as f64) as f32;
            leaf.weight += n as f64;
            if turns {
                leaf.axis = best;
            }
        }
        self.quad = out;
        self.accepted_before += epoch_records;
        // Records count over all epochs (the blend keeps what they taught), so an online
        // schedule of short epochs refines in space as an iterative one does.
        let total_weight: f64 = self.leaves.iter().map(|leaf| leaf.weight).sum();
        self.split_busy_leaves(self.settings.split_threshold(total_weight));
        self.sums = (0..self.quad.len() * 4).map(|_| atomic_f32::new(0.0)).collect();
        self.leaf_counts = (0..self.leaves.len()).map(|_| LeafCounts::default()).collect();
        self.refresh_derived();
    }

    fn stats(&self) -> GuideStats {
        let pending: u64 = self.leaf_counts.iter().map(|c| c.records() as u64).sum();
        let cells = 3 * self.quad.len() + self.leaves.len();
        GuideStats {
            regions: self.leaves.len(),
            entries_per_region: cells / self.leaves.len().max(1),
            memory_bytes: self.memory_bytes(),
            accepted_updates: self.accepted_before + pending,
            visited_entries: self.sums.iter().filter(|s| atomic_f32::load(s) > 0.0).count(),
            rejected_non_finite: self.rejected_non_finite.load(Ordering::Relaxed) as u64,
            rejected_negative: self.rejected_negative.load(Ordering::Relaxed) as u64,
            epochs: self.epoch,
        }
    }

    fn validate(&self) -> Result<(), Error> {
        super::serialize::validate(self)
    }

    fn to_bytes(&self) -> Vec<u8> {
        super::serialize::to_bytes(self)
    }

    fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        super::serialize::from_bytes(bytes)
    }

    fn merge(&mut self, other: &Self) -> Result<(), Error> {
        SpatialDirectionalTree::merge(self, other)
    }

    fn update_rule(&self) -> UpdateRule {
        self.settings.update_rule
    }
}

#[cfg(test)]
pub(super) mod tests;
