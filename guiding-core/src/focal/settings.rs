//! Configuration of a [`FocalGuide`](super::FocalGuide).

use crate::error::{require, Error};

/// Deepest octree level: a leaf of depth 16 spans 2⁻¹⁶ of the scene's largest side.
pub const MAX_FOCAL_DEPTH: u32 = 16;

/// Everything that shapes a focal guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocalGuideSettings {
    /// Most octree nodes (each 8 bytes of learning state plus its share of the sampling
    /// boxes); refinement stops there.
    pub max_nodes: u32,
    /// Deepest octree level, in 1..=[`MAX_FOCAL_DEPTH`].
    pub max_depth: u32,
    /// A leaf holding more than this share of the total mass splits in eight, in (0, 1).
    pub split_share: f32,
    /// A leaf is focal when its density (mass per m³) is at least this many times the
    /// mean density of the occupied leaves; only focal leaves are sampled.
    pub focal_ratio: f32,
    /// Most boxes sampled (the densest focal leaves): the pdf tests each one per
    /// direction.
    pub max_boxes: u32,
    /// Focal leaves that share a face and whose densities differ by at most this factor
    /// merge into one box before the heaviest `max_boxes` are kept (from the densest
    /// 4 × `max_boxes` leaves); 0 keeps every leaf its own box (the densest
    /// `max_boxes`).
    pub merge_ratio: f32,
    /// Points per recorded segment at which its mass is deposited (stratified along it);
    /// 0 deposits it exactly, into every leaf the segment crosses by the length inside.
    pub deposits_per_segment: u32,
    /// Cells of the selection grid along the scene's longest side (the others in
    /// proportion): each cell learns, from the directions its vertices drew, which
    /// probability of aiming at the boxes would have given the least variance
    /// (times `1 + share_cost` above 0).
    pub share_resolution: u32,
    /// The relative cost of a vertex that aims at the boxes (or uses any strategy whose
    /// share these cells learn) against one that does not, ≥ 0: a cell picks a share
    /// above 0 only where the variance it leaves, times `1 + share_cost`, is below the
    /// variance at share 0.
    pub share_cost: f32,
    /// Whether each cell of the selection grid learns its own probabilities of the boxes
    /// (by what its vertices' light came through; a quarter stays with the global masses)
    /// rather than drawing every box by its global mass. On by default. lodestar at 60 s,
    /// relMSE on ÷ off, seeds 41 and 42: guided-nee on door 160×120 0.960 and 0.954 (per
    /// sample 0.917 and 0.959), on Veach Ajar 0.924 and 0.941; guided (no next-event
    /// estimation, where the boxes carry more) on door 0.736 and 0.462, on cornell 128²
    /// 1.05 (per sample 0.98), on many_lights 160×120 at 30 s 0.720. A grid of more than
    /// 2²⁰ cells × boxes leaves it off.
    pub boxes_per_cell: bool,
}

impl Default for FocalGuideSettings {
    fn default() -> Self {
        Self {
            max_nodes: 1 << 16,
            max_depth: MAX_FOCAL_DEPTH,
            // Door 160×120, 60 s, p_focal 0.5 (relMSE): 1/512 and 32 boxes 9.6e-3 (with the
            // tree learning beside them), 1/2048 and 64 boxes 6.8e-3, 128 boxes 7.0e-3.
            split_share: 1.0 / 2048.0,
            focal_ratio: 16.0,
            max_boxes: 64,
            merge_ratio: 2.0,
            deposits_per_segment: 4,
            share_resolution: 8,
            share_cost: 0.0,
            boxes_per_cell: true,
        }
    }
}

impl FocalGuideSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), Error> {
        require(self.max_nodes >= 9, "max_nodes", self.max_nodes as f64, "at least 9 (a root and its children)")?;
        require((1..=MAX_FOCAL_DEPTH).contains(&self.max_depth), "max_depth", self.max_depth as f64, "in 1..=16")?;
        let share = self.split_share;
        require(share > 0.0 && share < 1.0, "split_share", share as f64, "in (0, 1)")?;
        let ratio = self.focal_ratio;
        require(ratio.is_finite() && ratio >= 1.0, "focal_ratio", ratio as f64, "finite and at least 1")?;
        require((1..=1024).contains(&self.max_boxes), "max_boxes", self.max_boxes as f64, "in 1..=1024")?;
        let merge = self.merge_ratio;
        require(
            merge == 0.0 || (merge.is_finite() && merge >= 1.0),
            "merge_ratio",
            merge as f64,
            "0 or finite and at least 1",
        )?;
        let deposits = self.deposits_per_segment;
        require(deposits <= 64, "deposits_per_segment", deposits as f64, "in 0..=64 (0: exact)")?;
        let cells = self.share_resolution;
        require((1..=64).contains(&cells), "share_resolution", cells as f64, "in 1..=64")?;
        let cost = self.share_cost;
        require(cost.is_finite() && cost >= 0.0, "share_cost", cost as f64, "finite and at least 0")
    }
}
