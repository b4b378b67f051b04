//! Configuration of a [`SpatialDirectionalTree`](super::SpatialDirectionalTree).

use crate::error::{require, Error};
use crate::update_rule::{IntegralEstimator, LearningRate, UpdateRule};

/// Deepest spatial level (a leaf of depth 24 spans 2⁻⁸ of the scene along each axis).
pub const MAX_SPATIAL_DEPTH: u32 = 24;
/// Deepest directional level: a cell of depth 20 covers 4π·4⁻²⁰ sr (about 0.01°).
pub const MAX_DIRECTIONAL_DEPTH: u32 = 20;

/// Everything that shapes a spatial × directional tree and how it learns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialDirectionalTreeSettings {
    /// Memory budget for every node of both trees and the building statistics, bytes.
    /// Refinement stops (spatial splits first, then directional depth) where it would
    /// pass it.
    pub budget_bytes: usize,
    /// c of the spatial split rule: a leaf splits when it holds more than
    /// `max(min_split_records, c·√R)` records, R the records of the whole tree, both
    /// counted over every epoch learned from (a split halves a leaf's count). Müller et
    /// al. 2017 use c·√(2^k) with 2^k the samples per pixel of iteration k; √R grows the
    /// same way, does not depend on the image size, and lets short online epochs refine
    /// as far as long iterations do. 32 by default: against 8, at 20 s on door and
    /// cornell, a quarter of the leaves, 1.13–1.18× the paths/s and 0.93× the relMSE.
    pub spatial_threshold: f32,
    /// The least records that let a leaf split, whatever the epoch's size.
    pub min_split_records: u32,
    /// A leaf also splits, whatever its count (given `min_split_records` this epoch),
    /// when no world axis holds this share of its epoch's records' normals, in [0, 1];
    /// 0 never splits for it. Surfaces facing different ways (a corner, a table on a
    /// floor) share a leaf's one quadtree, and a normal off the leaf's axis samples it
    /// folded onto its hemisphere, that is, by the other surfaces' light. Default 0.97:
    /// the reference tracer's guided on door 160×120 (`--p-focal 0 --guide-share
    /// fixed`, 30 s), relMSE × spp at seeds 41/42/43, 145/141/211 against 309/384/321
    /// at 0.
    pub mixed_normal_share: f32,
    /// A directional cell holding more than this share of its leaf's flux is split in
    /// four; an inner cell holding less is merged (Müller et al.'s ρ, 0.01).
    pub flux_fraction: f32,
    /// Deepest directional level, in 1..=[`MAX_DIRECTIONAL_DEPTH`].
    pub max_directional_depth: u32,
    /// Deepest spatial level, in 0..=[`MAX_SPATIAL_DEPTH`].
    pub max_spatial_depth: u32,
    /// Share of the sampling density spread uniformly over the normal's hemisphere, in
    /// [0, 1]: every direction above the surface keeps a pdf of at least
    /// `uniform_mix / 2π`.
    pub uniform_mix: f32,
    /// Sample only the normal's hemisphere: a direction drawn below the surface is
    /// mirrored in the tangent plane, with the exact pdf p(ω) + p(mirror ω). The tree is
    /// spherical because a leaf holds both sides of thin walls.
    pub fold_to_hemisphere: bool,
    /// Where the normal lies along the leaf's axis, sample the tree's density times
    /// cos θ to that axis rather than the density alone (Q·cos, the scattering
    /// integrand of a diffuse surface, as the hemisphere grid's `cosine_product`).
    /// Default on: as for `mixed_normal_share` (both on), relMSE × spp 115/114/118
    /// against 151/150/137 off.
    pub cosine_product: bool,
    /// One spatial tree per world axis, each for the surfaces whose normal lies nearest
    /// that axis (largest |component|), its leaves' squares built around it for good:
    /// surfaces facing different ways never share a leaf (a corner's floor and walls
    /// learn apart at any size), and an aligned normal always samples one half of its
    /// leaf's square (one descent, never the fold's two). Off: one spatial tree whose
    /// leaves turn their square to the axis most of their records' normals lie along,
    /// and split where their normals are mixed (`mixed_normal_share`). Default off: the
    /// reference tracer's guided (`--guide tree --p-focal 0 --guide-share fixed`, 30 s),
    /// relMSE × spp on ÷ off, door 160×120 seeds 41/42/43 185/200/181 against
    /// 108/109/112, cornell 128² seeds 41/42 1.96/1.93 against 1.61/1.52: the mixed split
    /// refines space along every edge and corner, and that finer space pays more than
    /// keeping the surfaces apart (on, halving the split constant to 16 or 8 for as many
    /// leaves as off gave 166 and 141 on door). On is the lighter and faster tree (the
    /// criterion bench: 173 ns against 203 ns a vertex, 0.5 MB against 2.6 MB).
    pub trees_per_axis: bool,
    /// Fit each directional cell to the root mean square of the radiance arriving there,
    /// √(Ω·∫ L² dω), rather than to its mean (Rath et al. 2020, variance-aware path
    /// guiding): directions whose arrivals vary (a bright source seen now and then)
    /// get more samples than their mean alone asks for. Records add target²/pdf; Q and
    /// [`q`](super::SpatialDirectionalTree::q) are then that RMS radiance. Default on:
    /// the reference tracer's guided (`--guide tree --p-focal 0 --guide-share fixed`,
    /// 30 s), relMSE × spp on against off, seeds 41/42, door 160×120 105.2/105.3 against
    /// 114.0/108.7, cornell 128² 1.527/1.524 against 1.569/1.590.
    pub second_moment: bool,
    /// How the epochs' flux estimates combine ([`LearningRate`]: simple averaging weighs
    /// every record alike, a constant α blends each epoch in, `Global` decays by epoch)
    /// and how the target's integral is estimated ([`IntegralEstimator::PathContinuation`]
    /// by default: the radiance the path itself brought back, no lookup).
    pub update_rule: UpdateRule,
}

impl Default for SpatialDirectionalTreeSettings {
    fn default() -> Self {
        Self {
            budget_bytes: 16 << 20,
            spatial_threshold: 32.0,
            min_split_records: 512,
            mixed_normal_share: 0.97,
            flux_fraction: 0.01,
            max_directional_depth: MAX_DIRECTIONAL_DEPTH,
            max_spatial_depth: MAX_SPATIAL_DEPTH,
            uniform_mix: 0.02,
            fold_to_hemisphere: true,
            cosine_product: true,
            trees_per_axis: false,
            second_moment: true,
            update_rule: UpdateRule {
                learning_rate: LearningRate::SimpleAverage,
                integral: IntegralEstimator::PathContinuation,
            },
        }
    }
}

impl SpatialDirectionalTreeSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        self.update_rule.validate()?;
        require(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        let c = self.spatial_threshold;
        require(c.is_finite() && c > 0.0, "spatial_threshold", c as f64, "finite and > 0")?;
        let mixed = self.mixed_normal_share;
        require((0.0..=1.0).contains(&mixed), "mixed_normal_share", mixed as f64, "in [0, 1]")?;
        let rho = self.flux_fraction;
        require(rho > 0.0 && rho < 1.0, "flux_fraction", rho as f64, "in (0, 1)")?;
        let depth = self.max_directional_depth;
        require((1..=MAX_DIRECTIONAL_DEPTH).contains(&depth), "max_directional_depth", depth as f64, "in 1..=20")?;
        let depth = self.max_spatial_depth;
        require(depth <= MAX_SPATIAL_DEPTH, "max_spatial_depth", depth as f64, "in 0..=24")?;
        let mix = self.uniform_mix;
        require((0.0..=1.0).contains(&mix), "uniform_mix", mix as f64, "in [0, 1]")?;
        // An integral estimated from Q would read the RMS radiance as the mean and feed
        // it back into the targets.
        let path = self.update_rule.integral == IntegralEstimator::PathContinuation;
        require(
            path || !self.second_moment,
            "second_moment",
            1.0,
            "off unless the integral estimator is the path's continuation",
        )?;
        Ok(())
    }

    /// These settings learning by `update_rule`, the second moment kept only where the
    /// rule's integral is the path's continuation (an integral read from Q would take
    /// the root mean square for the mean and feed it back): the defaults with any rule.
    /// A second moment asked for beside another integral afterwards is still refused by
    /// [`validate`](Self::validate).
    pub fn with_update_rule(self, update_rule: UpdateRule) -> Self {
        let second_moment = self.second_moment && update_rule.integral == IntegralEstimator::PathContinuation;
        Self { update_rule, second_moment, ..self }
    }

    /// How many spatial trees the settings keep: three with `trees_per_axis`, else one.
    pub fn spatial_tree_count(&self) -> usize {
        if self.trees_per_axis {
            3
        } else {
            1
        }
    }

    /// The records above which a leaf splits when the tree holds `records` in all.
    pub fn split_threshold(&self, records: f64) -> f64 {
        (self.spatial_threshold as f64 * libm::sqrt(records.max(0.0))).max(self.min_split_records as f64)
    }
}
