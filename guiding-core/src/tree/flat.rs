//! [`FlatTree`]: a [`SpatialDirectionalTree`]'s sampling state as flat arrays of words,
//! in the layout a GPU shader reads (storage buffers of `u32` and `f32`), and the
//! constants its distribution is built with, so another implementation of the same
//! descent cannot drift from this one.

use alloc::vec::Vec;

use glam::Vec3;

use super::guide::{SpatialDirectionalTree, LEAF_BYTES};
use super::quadtree::NODE_BYTES;
use super::spatial::{LEAF, SPATIAL_NODE_BYTES};

/// What a [`SpatialDirectionalTree`] samples by, as flat words (its learning state, the
/// building sums and counts, stays in the tree). Built by [`SpatialDirectionalTree::flat`].
///
/// A locate maps the point into the box's unit cube, `(position − low) · inverse_extent`
/// clamped to [0, 1), and descends from `roots[tree]` (a node index, or
/// [`FlatTree::LEAF`] | leaf index): at node `n`, with `axis = spatial[3n + 2]`, the
/// coordinate along the axis is doubled; at or past 1 the point moves to the high half
/// (`spatial[3n + 1]`, the coordinate less one), else to the low one (`spatial[3n]`).
/// A leaf's square is Lambert's cylindrical equal-area map of the sphere about its axis
/// (u = (z + 1)/2, v = φ/2π + 1/2, z along the axis); its quadtree's cells are ordered
/// (u low, v low), (u high, v low), (u low, v high), (u high, v high).
#[derive(Clone, Debug, PartialEq)]
pub struct FlatTree {
    /// The box's low corner, scene units.
    pub low: Vec3,
    /// One over the box's extent per axis, per scene unit.
    pub inverse_extent: Vec3,
    /// The spatial trees' roots: one, or one per world axis (x, y, z), picked by the
    /// normal's largest component ([`trees_per_axis`](Self::trees_per_axis)).
    pub roots: Vec<u32>,
    /// Whether a locate picks its tree by the normal's dominant axis.
    pub trees_per_axis: bool,
    /// Three words per inner spatial node: the low half's reference, the high half's,
    /// and the axis (0, 1, 2) the node halves its box along.
    pub spatial: Vec<u32>,
    /// Four words per leaf: its quadtree's root node, the world axis its square is built
    /// around, the axis its next split would halve (the point's half along it says which
    /// half of the leaf a record counts in), and its flux ∫ L dω over the sphere as f32
    /// bits (radiance × sr).
    pub leaves: Vec<u32>,
    /// Four words per quadtree node: each cell's child node, or 0 for a leaf cell.
    pub quad_children: Vec<u32>,
    /// Four per quadtree node: each cell's probability within the node (they sum to one).
    pub quad_probabilities: Vec<f32>,
    /// Four per quadtree node: each cell's probability under the tree's density times
    /// cos θ to the leaf's axis, which the half of the square above an aligned normal is
    /// sampled by; empty where the settings leave the cosine product off.
    pub cosine_probabilities: Vec<f32>,
    /// The share of a region's samples spread uniformly over its hemisphere.
    pub uniform_mix: f32,
    /// Whether a region's distribution keeps to the normal's hemisphere (else the whole
    /// sphere, as the quadtree has it).
    pub fold_to_hemisphere: bool,
}

impl FlatTree {
    /// Marks a spatial reference as a leaf index rather than a node index.
    pub const LEAF: u32 = LEAF;

    /// A normal whose component along a leaf's axis is at least this (in magnitude)
    /// samples the half of the square on its side; any other folds the sphere onto its
    /// hemisphere.
    pub const ALIGNED_COS: f32 = super::distribution::ALIGNED_COS;

    /// A half holding less than this share of the cells' probability is not sampled on
    /// its own: the region then samples its hemisphere uniformly.
    pub const MIN_HALF_MASS: f32 = super::distribution::MIN_HALF_MASS;
}

impl SpatialDirectionalTree {
    /// The tree's sampling state as flat arrays, for another implementation of its
    /// descent (a GPU shader). Allocates; call between passes.
    ///
    /// ```
    /// use guiding_core::{glam::Vec3, FlatTree, SpatialDirectionalTree, SpatialDirectionalTreeSettings};
    /// let settings = SpatialDirectionalTreeSettings { trees_per_axis: false, ..Default::default() };
    /// let tree = SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, settings).unwrap();
    /// let flat = tree.flat();
    /// assert_eq!(flat.roots, [FlatTree::LEAF]); // one tree, its root a leaf
    /// assert_eq!(flat.leaves.len(), 4);
    /// assert_eq!(flat.quad_probabilities, [0.25; 4]);
    /// ```
    pub fn flat(&self) -> FlatTree {
        let spatial = self.spatial.iter().flat_map(|n| [n.child[0], n.child[1], n.axis]).collect();
        let leaves = self
            .leaves
            .iter()
            .flat_map(|l| [l.root, l.axis, l.extent.max_position() as u32, l.flux.to_bits()])
            .collect();
        FlatTree {
            low: self.low,
            inverse_extent: self.inverse_extent,
            roots: self.spatial_roots.clone(),
            trees_per_axis: self.settings.trees_per_axis,
            spatial,
            leaves,
            quad_children: self.quad.iter().flat_map(|n| n.child).collect(),
            quad_probabilities: self.quad.iter().flat_map(|n| n.probability).collect(),
            cosine_probabilities: if self.settings.cosine_product {
                self.cosine.iter().flatten().copied().collect()
            } else {
                Vec::new()
            },
            uniform_mix: self.settings.uniform_mix,
            fold_to_hemisphere: self.settings.fold_to_hemisphere,
        }
    }

    /// The most spatial leaves and directional quadtree nodes the tree can hold within
    /// its byte budget (each at least; an upload sized for these never needs to grow).
    pub fn capacity(&self) -> (usize, usize) {
        let budget = self.settings.budget_bytes;
        // Every leaf past the first of its tree comes with an inner node.
        let leaves = self.spatial_roots.len() + budget / (LEAF_BYTES + SPATIAL_NODE_BYTES);
        (leaves, budget / NODE_BYTES)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;
    use crate::tree::square::axis_square;
    use crate::{DirectionalDistribution, SpatialDirectionalTreeSettings};

    /// A tree taught a light in one corner until space and directions both split.
    fn taught(settings: SpatialDirectionalTreeSettings) -> SpatialDirectionalTree {
        let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
        let mut rng = Pcg32::new(11, 2);
        let light = Vec3::new(0.6, 0.8, 0.0);
        for _ in 0..6 {
            for _ in 0..20_000 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let region = tree.locate(p, Vec3::Y).unwrap();
                let s = tree.sample(region, rng.next_vec2());
                let target = if s.direction.dot(light) > 0.95 { 30.0 } else { 0.1 };
                tree.update_sampled(region, s.direction, target, s.pdf);
            }
            tree.rebuild_sampling();
        }
        assert!(tree.leaf_count() > 4 && tree.directional_node_count() > 4 * tree.leaf_count());
        tree
    }

    /// The flat arrays, read as their documentation says, find the tree's leaves and
    /// densities.
    #[test]
    fn the_documented_descent_of_the_flat_arrays_finds_what_the_tree_finds() {
        for trees_per_axis in [false, true] {
            let settings =
                SpatialDirectionalTreeSettings { trees_per_axis, min_split_records: 1, ..Default::default() };
            let tree = taught(settings);
            let flat = tree.flat();
            let (leaves, nodes) = tree.capacity();
            assert!(tree.leaf_count() <= leaves && tree.directional_node_count() <= nodes);
            assert_eq!(flat.cosine_probabilities.len(), flat.quad_probabilities.len());
            let mut rng = Pcg32::new(5, 5);
            for _ in 0..20_000 {
                let position = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.4 - 1.2;
                let normal = crate::tree::square::square_to_direction(rng.next_vec2());
                let region = tree.locate(position, normal).unwrap();
                // The locate.
                let tree_index = if flat.trees_per_axis { normal.abs().max_position() } else { 0 };
                let mut p = ((position - flat.low) * flat.inverse_extent)
                    .clamp(Vec3::ZERO, Vec3::splat(crate::tree::square::ONE_BELOW));
                let mut reference = flat.roots[tree_index];
                while reference & FlatTree::LEAF == 0 {
                    let n = reference as usize;
                    let axis = flat.spatial[3 * n + 2] as usize;
                    let x = p[axis] * 2.0;
                    let high = x >= 1.0;
                    p[axis] = if high { x - 1.0 } else { x };
                    reference = flat.spatial[3 * n + high as usize];
                }
                let leaf = (reference & !FlatTree::LEAF) as usize;
                assert_eq!(leaf as u32, region.leaf);
                assert_eq!(p[flat.leaves[4 * leaf + 2] as usize] >= 0.5, region.upper_half);
                // The quadtree's density at a direction: Q over the flux.
                let direction = crate::tree::square::square_to_direction(rng.next_vec2());
                let mut square = axis_square(direction, flat.leaves[4 * leaf + 1]);
                let (mut node, mut density) = (flat.leaves[4 * leaf] as usize, 1.0f32);
                loop {
                    let cell = (square.x >= 0.5) as usize + 2 * (square.y >= 0.5) as usize;
                    square = square * 2.0 - glam::Vec2::new((cell & 1) as f32, (cell >> 1) as f32);
                    density *= 4.0 * flat.quad_probabilities[4 * node + cell];
                    match flat.quad_children[4 * node + cell] {
                        0 => break,
                        child => node = child as usize,
                    }
                }
                let flux = f32::from_bits(flat.leaves[4 * leaf + 3]);
                let q = flux * density / (4.0 * core::f32::consts::PI);
                assert!(
                    (q - tree.q(region, direction)).abs() <= 1e-5 * q.max(1e-6),
                    "{q} vs {}",
                    tree.q(region, direction)
                );
            }
            // The distribution the constants describe: an aligned normal samples its half.
            let region = tree.locate(Vec3::ZERO, Vec3::Y).unwrap();
            let d = tree.distribution(region);
            assert!(d.pdf(-Vec3::Y) == 0.0 && d.pdf(Vec3::Y) > 0.0);
        }
    }
}
