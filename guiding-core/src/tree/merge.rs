//! Merging two trees learned over the same box with the same settings: the union of
//! their spatial and directional subdivisions, each cell's flux the two trees' mean
//! weighted by the records their leaves learned from.

use alloc::vec::Vec;

use super::axis::{rotated_cells, LeafCounts, ROTATED_SIDE};
use super::guide::{bytes_for, SpatialDirectionalTree, SpatialLeaf};
use super::quadtree::{self, QuadNode, NODE_BYTES};
use super::spatial::{Parent, SpatialNode, LEAF};
use crate::atomic_f32;
use crate::error::Error;
use crate::update_rule::add_rejected_counts;

/// One leaf of the union: the leaf of each tree its box lies in, and the share of that
/// leaf's box it covers (1, or a half per split the other tree made below it).
struct Piece {
    mine: u32,
    mine_share: f64,
    theirs: u32,
    theirs_share: f64,
    parent: Parent,
}

/// One tree's part of a directional cell: the quadtree node below it (`None` where the
/// tree has a leaf cell there, which counts as uniform inside) and its flux.
#[derive(Clone, Copy)]
struct Part<'a> {
    nodes: &'a [QuadNode],
    node: Option<u32>,
    flux: f64,
}

impl Part<'_> {
    fn cell(&self, cell: usize) -> Self {
        let (share, child) = match self.node {
            Some(node) => {
                let node = &self.nodes[node as usize];
                (node.probability[cell] as f64, Some(node.child[cell]).filter(|&c| c != 0))
            }
            None => (0.25, None),
        };
        Part { nodes: self.nodes, node: child, flux: self.flux * share }
    }
}

impl SpatialDirectionalTree {
    /// Adds what `other` learned. Both must cover the same box with the same settings,
    /// and neither may hold records since its last
    /// [`rebuild_sampling`](crate::Guide::rebuild_sampling); otherwise nothing changes
    /// and the difference is named.
    ///
    /// The result is the union of both subdivisions: a spatial leaf wherever either tree
    /// has one, and in it a directional quadtree split wherever either leaf's was, each
    /// cell holding the mean of both trees' flux there weighted by the records each leaf
    /// learned from (a coarser leaf or cell counting as uniform over the finer ones it
    /// covers, with its share of the records). The directional trees are capped by the
    /// byte budget as a refit caps them; a union whose spatial tree alone does not fit is
    /// refused.
    ///
    /// This is an approximation, not the tree one process would have learned from every
    /// record: that tree would have refined by the combined flux, and a leaf's square
    /// built around another axis is resampled at 16×16 cells to turn it. The records'
    /// flux is kept: where both trees have one shape, every cell's flux is exactly the
    /// record-weighted mean.
    pub fn merge(&mut self, other: &SpatialDirectionalTree) -> Result<(), Error> {
        if self.settings != other.settings {
            return Err(Error::Incompatible { what: "settings" });
        }
        if self.low != other.low || self.extent != other.extent {
            return Err(Error::Incompatible { what: "bounds" });
        }
        let pending = |tree: &SpatialDirectionalTree| tree.leaf_counts.iter().any(|c| c.records() > 0);
        if pending(self) || pending(other) {
            return Err(Error::Incompatible { what: "records pending since the last rebuild_sampling" });
        }
        let (mut spatial, mut pieces) = (Vec::new(), Vec::new());
        let mut roots = Vec::with_capacity(self.spatial_roots.len());
        for (tree, (&mine, &theirs)) in self.spatial_roots.iter().zip(&other.spatial_roots).enumerate() {
            let parent = Parent::Root { tree: tree as u32 };
            roots.push(union_spatial([self, other], [(mine, 1.0), (theirs, 1.0)], parent, &mut spatial, &mut pieces)?);
        }

        let budget = self.settings.budget_bytes;
        let fixed = bytes_for(spatial.len(), pieces.len(), 0);
        let needed_bytes = fixed + pieces.len() * NODE_BYTES;
        if needed_bytes > budget {
            return Err(Error::OverBudget { regions: pieces.len(), needed_bytes, budget_bytes: budget });
        }
        let node_budget = (budget - fixed) / NODE_BYTES;
        let mut quad = Vec::with_capacity(self.quad.len() + other.quad.len());
        let mut leaves = Vec::with_capacity(pieces.len());
        let mut turned = Vec::new();
        for (index, piece) in pieces.iter().enumerate() {
            let (a, b) = (self.leaves[piece.mine as usize], other.leaves[piece.theirs as usize]);
            let (wa, wb) = (a.weight * piece.mine_share, b.weight * piece.theirs_share);
            // Weighted by records; a leaf that learned from none (set by hand, or fresh)
            // counts only where it holds flux.
            let (ka, kb) = match (wa + wb > 0.0, a.flux > 0.0, b.flux > 0.0) {
                (true, _, _) => (wa / (wa + wb), wb / (wa + wb)),
                (false, true, false) => (1.0, 0.0),
                (false, false, true) => (0.0, 1.0),
                (false, _, _) => (0.5, 0.5),
            };
            // The square is built around the heavier leaf's axis; the other leaf's is
            // turned to it where they differ.
            let axis = if wb > wa { b.axis } else { a.axis };
            let sources = [(&self.quad[..], a), (&other.quad[..], b)];
            turned.clear();
            let parts = [0, 1].map(|t| {
                let (nodes, leaf) = sources[t];
                let flux = [ka, kb][t] * leaf.flux as f64;
                if leaf.axis == axis {
                    return (nodes, leaf.root, flux, false);
                }
                let cells = rotated_cells(nodes, leaf.root, leaf.axis, axis);
                (nodes, quadtree::full_tree(&cells, ROTATED_SIDE, 0, 0, ROTATED_SIDE, &mut turned).0, flux, true)
            });
            let parts = parts.map(|(nodes, root, flux, is_turned)| Part {
                nodes: if is_turned { &turned[..] } else { nodes },
                node: Some(root),
                flux,
            });
            let cap = node_budget.saturating_sub(pieces.len() - index - 1).max(quad.len() + 1);
            let max_depth = self.settings.max_directional_depth;
            let root = union_directions(parts, 0, max_depth, cap, &mut quad);
            let flux = parts[0].flux + parts[1].flux;
            // The leaf lying whole in the piece (share 1) gives its exact box.
            let whole = if piece.mine_share == 1.0 { a } else { b };
            leaves.push(SpatialLeaf {
                root,
                flux: flux.min(f32::MAX as f64) as f32,
                weight: wa + wb,
                parent: piece.parent,
                extent: whole.extent,
                depth: whole.depth,
                axis,
            });
        }
        self.spatial = spatial;
        self.spatial_roots = roots;
        self.leaf_counts = (0..leaves.len()).map(|_| LeafCounts::default()).collect();
        self.leaves = leaves;
        self.sums = (0..quad.len() * 4).map(|_| atomic_f32::new(0.0)).collect();
        self.quad = quad;
        self.refresh_derived();
        self.epoch = self.epoch.max(other.epoch);
        self.accepted_before = self.accepted_before.saturating_add(other.accepted_before);
        add_rejected_counts(
            [&self.rejected_non_finite, &self.rejected_negative],
            [&other.rejected_non_finite, &other.rejected_negative],
        );
        Ok(())
    }
}

/// Appends the union of two spatial subtrees (`at`: each tree's child reference and
/// the share of its leaf's box the subtree covers) to `nodes`, and one piece per union
/// leaf to `pieces`; returns the union's reference.
fn union_spatial(
    trees: [&SpatialDirectionalTree; 2],
    at: [(u32, f64); 2],
    parent: Parent,
    nodes: &mut Vec<SpatialNode>,
    pieces: &mut Vec<Piece>,
) -> Result<u32, Error> {
    let leaf = at.map(|(reference, _)| reference & LEAF != 0);
    if leaf[0] && leaf[1] {
        let index = pieces.len() as u32;
        let [(mine, mine_share), (theirs, theirs_share)] = at.map(|(r, share)| (r & !LEAF, share));
        pieces.push(Piece { mine, mine_share, theirs, theirs_share, parent });
        return Ok(LEAF | index);
    }
    let axes = [0, 1].map(|t| (!leaf[t]).then(|| trees[t].spatial[at[t].0 as usize].axis));
    // Both trees split a box along its longest side: one box, one axis.
    let axis = match axes {
        [Some(a), Some(b)] if a != b => return Err(Error::Incompatible { what: "spatial splits" }),
        [Some(a), _] | [None, Some(a)] => a,
        [None, None] => unreachable!("one of the two is a node"),
    };
    let node = nodes.len() as u32;
    nodes.push(SpatialNode { child: [0; 2], axis });
    for side in 0..2 {
        let child = [0, 1].map(|t| {
            let (reference, share) = at[t];
            if leaf[t] {
                (reference, share * 0.5)
            } else {
                (trees[t].spatial[reference as usize].child[side], share)
            }
        });
        let reference = union_spatial(trees, child, Parent::Node { node, side: side as u32 }, nodes, pieces)?;
        nodes[node as usize].child[side] = reference;
    }
    Ok(node)
}

/// Appends the union of two directional subtrees to `out` (while it holds fewer than
/// `cap` nodes and `depth` allows); returns the new node's index.
fn union_directions(parts: [Part<'_>; 2], depth: u32, max_depth: u32, cap: usize, out: &mut Vec<QuadNode>) -> u32 {
    let index = out.len();
    let cells: [[Part<'_>; 2]; 4] = core::array::from_fn(|cell| parts.map(|part| part.cell(cell)));
    let flux = cells.map(|[a, b]| a.flux + b.flux);
    let sum: f64 = flux.iter().sum();
    let probability = if sum > 0.0 && sum.is_finite() { flux.map(|f| (f / sum) as f32) } else { [0.25; 4] };
    out.push(QuadNode { probability, child: [0; 4] });
    for (cell, pair) in cells.iter().enumerate() {
        let deeper = pair.iter().any(|part| part.node.is_some());
        if deeper && depth + 2 <= max_depth && out.len() < cap {
            let child = union_directions(*pair, depth + 1, max_depth, cap, out);
            out[index].child[cell] = child;
        }
    }
    index as u32
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::distribution::DirectionalDistribution;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;
    use crate::tree::SpatialDirectionalTreeSettings;

    const LIGHT: Vec3 = Vec3::new(0.6, 0.8, 0.0);

    fn tree(settings: SpatialDirectionalTreeSettings) -> SpatialDirectionalTree {
        SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).expect("a tree over the box")
    }

    /// Epochs of a peaked field (brighter toward +x in space) learned at points of
    /// `rng`, each epoch refitted.
    fn learn(tree: &mut SpatialDirectionalTree, rng: &mut Pcg32, epochs: u32, records: u32) {
        for _ in 0..epochs {
            for _ in 0..records {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let normal = if rng.next_f32() < 0.5 { Vec3::Y } else { Vec3::X };
                let region = tree.locate(p, normal).expect("inside");
                let s = tree.distribution(region).sample(rng.next_vec2());
                let target = if s.direction.dot(LIGHT) > 0.99 { 50.0 * (2.0 + p.x) } else { 0.1 };
                tree.update_sampled(region, s.direction, target, s.pdf);
            }
            tree.rebuild_sampling();
        }
    }

    fn directions(count: usize) -> Vec<Vec3> {
        let mut rng = Pcg32::new(77, 1);
        (0..count)
            .map(|_| {
                let u = rng.next_vec2();
                let z = 1.0 - 2.0 * u.x;
                let r = libm::sqrtf((1.0 - z * z).max(0.0));
                let phi = 2.0 * core::f32::consts::PI * u.y;
                Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z)
            })
            .collect()
    }

    fn points() -> [Vec3; 4] {
        [Vec3::new(0.7, 0.2, -0.3), Vec3::new(-0.8, -0.5, 0.9), Vec3::new(0.1, 0.9, 0.4), Vec3::splat(-0.2)]
    }

    /// The pdf of each of `directions` at each of [`points`], about +y.
    fn pdfs(tree: &SpatialDirectionalTree, directions: &[Vec3]) -> Vec<f32> {
        let mut out = Vec::new();
        for p in points() {
            let d = tree.distribution(tree.locate(p, Vec3::Y).expect("inside"));
            out.extend(directions.iter().map(|&w| d.pdf(w)));
        }
        out
    }

    #[test]
    fn a_fresh_tree_takes_a_learned_one_whole_and_gives_nothing_back() {
        let settings = SpatialDirectionalTreeSettings::default();
        let mut learned = tree(settings);
        learn(&mut learned, &mut Pcg32::new(1, 2), 6, 20_000);
        assert!(learned.leaf_count() > 1 && learned.directional_node_count() > learned.leaf_count());
        let d = directions(500);
        let reference = pdfs(&learned, &d);

        let mut fresh = tree(settings);
        fresh.merge(&learned).expect("same box and settings");
        assert_eq!(fresh.leaf_count(), learned.leaf_count());
        for (a, b) in pdfs(&fresh, &d).iter().zip(&reference) {
            assert!((a - b).abs() <= 1e-4 * b.max(1e-3), "{a} against {b}");
        }
        learned.merge(&tree(settings)).expect("same box and settings");
        for (a, b) in pdfs(&learned, &d).iter().zip(&reference) {
            assert!((a - b).abs() <= 1e-4 * b.max(1e-3), "{a} against {b}");
        }
        learned.validate().expect("a valid tree");
    }

    #[test]
    fn a_tree_merged_with_itself_keeps_its_distribution_and_doubles_its_records() {
        let settings = SpatialDirectionalTreeSettings::default();
        let mut learned = tree(settings);
        learn(&mut learned, &mut Pcg32::new(3, 4), 5, 20_000);
        let d = directions(500);
        let (reference, records) = (pdfs(&learned, &d), learned.stats().accepted_updates);
        // The union lists its leaves in its own order: compared sorted.
        let sorted_flux = |tree: &SpatialDirectionalTree| {
            let mut flux: Vec<f32> = (0..tree.leaf_count() as u32).map(|l| tree.leaf_flux(l)).collect();
            flux.sort_by(f32::total_cmp);
            flux
        };
        let flux = sorted_flux(&learned);
        let copy = learned.clone();
        learned.merge(&copy).expect("same box and settings");
        for (a, b) in pdfs(&learned, &d).iter().zip(&reference) {
            assert!((a - b).abs() <= 1e-4 * b.max(1e-3), "{a} against {b}");
        }
        let merged = sorted_flux(&learned);
        assert_eq!(merged.len(), flux.len());
        for (a, b) in merged.iter().zip(&flux) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1e-6), "{a} against {b}");
        }
        assert_eq!(learned.stats().accepted_updates, 2 * records);
    }

    #[test]
    fn halves_learned_apart_merge_near_the_tree_that_learned_them_all() {
        let settings = SpatialDirectionalTreeSettings::default();
        let (mut a, mut b, mut all) = (tree(settings), tree(settings), tree(settings));
        learn(&mut a, &mut Pcg32::new(5, 1), 6, 10_000);
        learn(&mut b, &mut Pcg32::new(6, 1), 6, 10_000);
        learn(&mut all, &mut Pcg32::new(7, 1), 6, 20_000);
        a.merge(&b).expect("same box and settings");
        a.validate().expect("a valid tree");
        assert!(a.memory_bytes() <= settings.budget_bytes);
        let away = Vec3::new(-0.6, 0.8, 0.0);
        for p in points() {
            let (ra, rall) = (a.locate(p, Vec3::Y).unwrap(), all.locate(p, Vec3::Y).unwrap());
            let (merged, learned) = (a.distribution(ra).pdf(LIGHT), all.distribution(rall).pdf(LIGHT));
            assert!(merged > 10.0 * a.distribution(ra).pdf(away), "the merged tree finds the light at {p}");
            assert!(merged > 0.4 * learned && merged < 2.5 * learned, "{merged} against {learned} at {p}");
        }
    }

    #[test]
    fn unions_past_the_budget_are_capped_and_other_trees_are_refused() {
        let small = SpatialDirectionalTreeSettings { budget_bytes: 24 << 10, ..Default::default() };
        let (mut a, mut b) = (tree(small), tree(small));
        learn(&mut a, &mut Pcg32::new(8, 1), 6, 20_000);
        learn(&mut b, &mut Pcg32::new(9, 1), 6, 20_000);
        a.merge(&b).expect("the spatial union fits");
        assert!(a.memory_bytes() <= small.budget_bytes, "{} bytes", a.memory_bytes());
        a.validate().expect("a valid tree");

        let elsewhere = SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, small).expect("a tree");
        assert_eq!(a.merge(&elsewhere), Err(Error::Incompatible { what: "bounds" }));
        let other_settings = SpatialDirectionalTreeSettings { flux_fraction: 0.02, ..small };
        assert_eq!(a.merge(&tree(other_settings)), Err(Error::Incompatible { what: "settings" }));
        let busy = tree(small);
        let region = busy.locate(Vec3::ZERO, Vec3::Y).unwrap();
        busy.update_sampled(region, Vec3::Y, 1.0, 0.5);
        let before = a.to_bytes();
        let refused = a.merge(&busy);
        assert_eq!(refused, Err(Error::Incompatible { what: "records pending since the last rebuild_sampling" }));
        assert_eq!(a.to_bytes(), before, "a refused merge changes nothing");
    }
}
