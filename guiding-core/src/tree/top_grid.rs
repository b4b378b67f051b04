//! [`TopGrid`]: a uniform grid over the spatial trees' box whose every cell names the
//! deepest node of its spatial tree that holds the whole cell, and how often that node's
//! box was halved along each axis. A locate starts there, with the point's place in that
//! node's box computed at once, instead of descending the levels above one by one (each a
//! load that waits on the one before).

use alloc::vec::Vec;

use glam::Vec3;

use super::spatial::{SpatialNode, LEAF};

/// Where a locate starts for the points of one cell.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct TopEntry {
    /// A node index, or `LEAF | leaf index`.
    reference: u32,
    /// How often the node's box was halved along x, y and z.
    splits: [u8; 3],
}

/// Cells of the grid per inner node of the spatial trees, at most. On the benchmark's
/// tree (535 inner nodes) 8 gave 4096 cells and a vertex 172–180 ns, against 184–187 ns
/// with 512 cells (1 per node); 64 (32768 cells) was within the noise of 8.
const CELLS_PER_NODE: usize = 8;

/// Bytes the grid costs per inner node at most: the budget charges every inner node that.
pub(crate) const TOP_GRID_BYTES_PER_NODE: usize = CELLS_PER_NODE * core::mem::size_of::<TopEntry>();

/// The most halvings of the box per axis the grid resolves (32³ cells per tree).
const MAX_LEVELS: u32 = 5;

/// See the module documentation. Derived from the spatial trees, rebuilt whenever they
/// change; never serialized.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct TopGrid {
    /// Cells per axis are `1 << levels`; 0: no grid, a locate starts at the root.
    levels: u32,
    /// Per spatial tree its cells, x fastest.
    entries: Vec<TopEntry>,
}

impl TopGrid {
    /// The grid over the trees of `roots` in `nodes`, with at most [`CELLS_PER_NODE`]
    /// cells in all per inner node.
    pub(crate) fn build(nodes: &[SpatialNode], roots: &[u32]) -> Self {
        let trees = roots.len().max(1);
        let mut levels = 0;
        while levels < MAX_LEVELS && trees << (3 * (levels + 1)) <= CELLS_PER_NODE * nodes.len() {
            levels += 1;
        }
        if levels == 0 {
            return Self::default();
        }
        let cells = 1usize << (3 * levels);
        let mut entries = alloc::vec![TopEntry::default(); roots.len() * cells];
        for (tree, &root) in roots.iter().enumerate() {
            let side = 1u32 << levels;
            let cell = Cell { origin: [0; 3], size: [side; 3], splits: [0; 3] };
            fill(nodes, root, cell, levels, &mut entries[tree * cells..(tree + 1) * cells]);
        }
        Self { levels, entries }
    }

    /// Bytes held.
    #[cfg(test)]
    pub(crate) fn memory_bytes(&self) -> usize {
        self.entries.len() * core::mem::size_of::<TopEntry>()
    }

    /// Where the locate of the point `p` (in the box's unit cube, each coordinate in
    /// [0, 1)) in spatial tree `tree` of root `root` starts: a node reference, and `p` in
    /// that node's unit cube (as a descent from the root would have it, exactly).
    #[inline]
    pub(crate) fn start(&self, tree: usize, root: u32, p: Vec3) -> (u32, Vec3) {
        if self.levels == 0 {
            return (root, p);
        }
        // Scaling by a power of two is exact, and p < 1 keeps each cell below the side.
        let side = (1u32 << self.levels) as f32;
        let c = p * side;
        let (x, y, z) = (c.x as usize, c.y as usize, c.z as usize);
        let index = (tree << (3 * self.levels)) + x + (y << self.levels) + (z << (2 * self.levels));
        let Some(entry) = self.entries.get(index) else { return (root, p) };
        // frac(p·2^s): what s halvings along an axis leave of p, each exact.
        let scaled =
            p * Vec3::new(power_of_two(entry.splits[0]), power_of_two(entry.splits[1]), power_of_two(entry.splits[2]));
        let whole = Vec3::new((scaled.x as u32) as f32, (scaled.y as u32) as f32, (scaled.z as u32) as f32);
        (entry.reference, scaled - whole)
    }
}

/// 2^s as f32, for s ≤ MAX_LEVELS.
#[inline]
fn power_of_two(s: u8) -> f32 {
    f32::from_bits((127 + s as u32) << 23)
}

/// A box of cells: its first cell, its size in cells and the halvings that made it.
#[derive(Clone, Copy)]
struct Cell {
    origin: [u32; 3],
    size: [u32; 3],
    splits: [u8; 3],
}

/// Fills the cells of `cell`'s box with `reference`, or with the nodes below it where
/// its halves are still whole cells. Each call halves a side of at least two cells, so
/// the recursion ends within 3·`levels` calls deep, whatever the nodes hold.
fn fill(nodes: &[SpatialNode], reference: u32, cell: Cell, levels: u32, out: &mut [TopEntry]) {
    if reference & LEAF == 0 {
        if let Some(node) = nodes.get(reference as usize) {
            // A damaged axis reads as z, as the descent reads it.
            let axis = node.axis.min(2) as usize;
            if cell.size[axis] >= 2 {
                let half = cell.size[axis] / 2;
                let mut low = cell;
                low.size[axis] = half;
                low.splits[axis] += 1;
                let mut high = low;
                high.origin[axis] += half;
                fill(nodes, node.child[0], low, levels, out);
                fill(nodes, node.child[1], high, levels, out);
                return;
            }
        }
    }
    let entry = TopEntry { reference, splits: cell.splits };
    let [x0, y0, z0] = cell.origin;
    for z in z0..z0 + cell.size[2] {
        for y in y0..y0 + cell.size[1] {
            for x in x0..x0 + cell.size[0] {
                out[(x + (y << levels) + (z << (2 * levels))) as usize] = entry;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;
    use crate::tree::spatial::{descend_to_leaf, split_leaf, Parent};

    /// A tree split unevenly, deeper in one corner than the grid resolves.
    fn uneven_tree() -> (Vec<SpatialNode>, [u32; 1]) {
        let (mut nodes, mut roots) = (Vec::new(), [LEAF]);
        let mut leaves = 1u32;
        // Splits the leaf holding `p` along `axis`.
        let mut split_at = |nodes: &mut Vec<SpatialNode>, roots: &mut [u32; 1], p: Vec3, axis: u32| {
            let mut parent = Parent::Root { tree: 0 };
            let (mut reference, mut q) = (roots[0], p);
            while reference & LEAF == 0 {
                let node = nodes[reference as usize];
                let x = q[node.axis as usize] * 2.0;
                let side = (x >= 1.0) as u32;
                q[node.axis as usize] = if x >= 1.0 { x - 1.0 } else { x };
                parent = Parent::Node { node: reference, side };
                reference = node.child[side as usize];
            }
            split_leaf(nodes, roots, parent, reference & !LEAF, leaves, axis);
            leaves += 1;
        };
        for level in 0..20u32 {
            let corner = Vec3::splat(0.01);
            split_at(&mut nodes, &mut roots, corner, level % 3);
            // And a few elsewhere, shallower.
            if level < 6 {
                split_at(&mut nodes, &mut roots, Vec3::new(0.8, 0.3, 0.6), (level + 1) % 3);
            }
        }
        (nodes, roots)
    }

    #[test]
    fn starting_from_the_grid_finds_the_leaf_and_position_the_root_finds() {
        let (nodes, roots) = uneven_tree();
        let grid = TopGrid::build(&nodes, &roots);
        assert!(grid.levels >= 1, "{} nodes give a grid", nodes.len());
        assert!(grid.memory_bytes() <= nodes.len() * TOP_GRID_BYTES_PER_NODE);
        let mut rng = Pcg32::new(5, 9);
        for i in 0..100_000 {
            let p = if i % 2 == 0 {
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
            } else {
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.03
            };
            let (start, local) = grid.start(0, roots[0], p);
            assert_eq!(descend_to_leaf(&nodes, start, local), descend_to_leaf(&nodes, roots[0], p), "at {p}");
        }
        // Too few nodes for a grid: the root.
        let empty = TopGrid::build(&nodes[..0], &roots);
        assert_eq!(empty.start(0, roots[0], Vec3::splat(0.5)), (roots[0], Vec3::splat(0.5)));
    }

    #[test]
    fn damaged_nodes_end_the_fill_without_a_panic() {
        // A cycle and an index past the end: the fill stops at the grid's resolution.
        let nodes = alloc::vec![SpatialNode { child: [0, 99], axis: 7 }; 1];
        let grid = TopGrid::build(&nodes, &[0]);
        assert_eq!(grid.levels, 1);
        let (start, _) = grid.start(0, 0, Vec3::splat(0.75));
        assert_eq!(start, 99);
    }
}
