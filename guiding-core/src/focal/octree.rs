//! The octree that learns where light-carrying segments pass: mass (segment weight ×
//! length) per leaf, added lock-free during a pass, refined between passes.

use alloc::vec::Vec;
use core::sync::atomic::AtomicU32;

use glam::Vec3;

use crate::atomic_f32;

/// Most leaves one segment deposits into leaf by leaf; what lies beyond goes to the last.
pub(crate) const MAX_LEAVES_PER_SEGMENT: u32 = 1024;

/// A leaf as the sampler sees it: its node, its cube and its mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Leaf {
    pub node: u32,
    pub low: Vec3,
    pub size: f32,
    pub depth: u32,
    pub mass: f32,
}

/// Nodes in one flat array, the root first; a node's eight children are contiguous.
pub(crate) struct FocalOctree {
    /// The root cube's corner and side, metres.
    pub low: Vec3,
    pub size: f32,
    /// Index of each node's first child; 0 marks a leaf (the root is nobody's child).
    pub children: Vec<u32>,
    /// Each node's mass (f32 bits); only leaves gather any.
    pub mass: Vec<AtomicU32>,
}

/// The child of a cube with corner `low` and side `size` that holds `p`: its index
/// (bit 0: x, bit 1: y, bit 2: z in the upper half), corner and side.
fn child_of(p: Vec3, low: Vec3, size: f32) -> (u32, Vec3) {
    let half = 0.5 * size;
    let upper = p.cmpge(low + Vec3::splat(half));
    let index = upper.bitmask();
    let offset = Vec3::select(upper, Vec3::splat(half), Vec3::ZERO);
    (index, low + offset)
}

impl FocalOctree {
    /// One leaf, the cube around the box `low`..`high` (1 % larger, so a point on the
    /// box's face is inside).
    pub fn new(low: Vec3, high: Vec3) -> Self {
        let extent = (high - low).max_element().max(1e-6);
        let size = extent * 1.01;
        let center = 0.5 * (low + high);
        Self {
            low: center - Vec3::splat(0.5 * size),
            size,
            children: alloc::vec![0],
            mass: alloc::vec![atomic_f32::new(0.0)],
        }
    }

    /// Whether `p` lies in the root cube.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.low).all() && p.cmplt(self.low + Vec3::splat(self.size)).all()
    }

    /// The leaf that holds `p`, if `p` is inside the root cube.
    pub fn leaf_at(&self, p: Vec3) -> Option<u32> {
        self.leaf_cube_at(p).map(|(leaf, _, _)| leaf)
    }

    /// The leaf that holds `p` with its cube's corner and side, if `p` is inside the root
    /// cube.
    pub fn leaf_cube_at(&self, p: Vec3) -> Option<(u32, Vec3, f32)> {
        if !self.contains(p) {
            return None;
        }
        let (mut node, mut low, mut size) = (0u32, self.low, self.size);
        loop {
            let first = self.children[node as usize];
            if first == 0 {
                return Some((node, low, size));
            }
            let (index, child_low) = child_of(p, low, size);
            node = first + index;
            low = child_low;
            size *= 0.5;
        }
    }

    /// Adds `weight` × (length inside) to every leaf the segment `origin` + t·`direction`,
    /// t in [`t0`, `t1`], crosses (at most [`MAX_LEAVES_PER_SEGMENT`], the rest to the
    /// last). `direction` is a unit vector; the segment lies inside the root cube.
    pub fn deposit_along(&self, origin: Vec3, direction: Vec3, (t0, t1): (f32, f32), weight: f32) {
        let inverse = direction.recip();
        // A step past each exit, so the next lookup lands in the next leaf.
        let nudge = 1e-6 * self.size;
        let mut t = t0;
        for crossed in 0..MAX_LEAVES_PER_SEGMENT {
            if t >= t1 {
                return;
            }
            let probe = origin + direction * (t + nudge).min(0.5 * (t + t1));
            let Some((leaf, low, size)) = self.leaf_cube_at(probe) else { return };
            let (_, exit) = crate::focal::lanes::ray_box(origin, inverse, low, low + Vec3::splat(size));
            let last = crossed + 1 == MAX_LEAVES_PER_SEGMENT;
            // A NaN or non-advancing exit (rounding at a face) ends the walk in this leaf.
            let advances = exit > t;
            let exit = if last || !advances { t1 } else { exit.min(t1) };
            let amount = weight * (exit - t);
            atomic_f32::update(&self.mass[leaf as usize], |m| m + amount);
            t = exit.max(t + nudge);
        }
    }

    /// Adds `amount` to the mass of the leaf holding `p` (nothing outside the cube).
    pub fn deposit(&self, p: Vec3, amount: f32) {
        if let Some(leaf) = self.leaf_at(p) {
            atomic_f32::update(&self.mass[leaf as usize], |m| m + amount);
        }
    }

    /// Every leaf, depth first.
    pub fn leaves(&self) -> Vec<Leaf> {
        let mut leaves = Vec::new();
        let mut stack = alloc::vec![(0u32, self.low, self.size, 0u32)];
        while let Some((node, low, size, depth)) = stack.pop() {
            let first = self.children[node as usize];
            if first == 0 {
                leaves.push(Leaf { node, low, size, depth, mass: atomic_f32::load(&self.mass[node as usize]) });
                continue;
            }
            let half = 0.5 * size;
            for index in 0..8u32 {
                let offset = Vec3::new((index & 1) as f32, ((index >> 1) & 1) as f32, ((index >> 2) & 1) as f32);
                stack.push((first + index, low + offset * half, half, depth + 1));
            }
        }
        leaves
    }

    /// Splits every leaf whose mass passes `threshold` (its children share its mass
    /// evenly, so densities stay as learned), again in the children while they still
    /// pass it, within `max_nodes` nodes and `max_depth` levels.
    pub fn split_heavy_leaves(&mut self, threshold: f32, max_nodes: u32, max_depth: u32) {
        let mut work: Vec<(u32, u32)> =
            self.leaves().into_iter().filter(|l| l.mass > threshold).map(|l| (l.node, l.depth)).collect();
        while let Some((node, depth)) = work.pop() {
            if depth >= max_depth || self.children.len() + 8 > max_nodes as usize {
                continue;
            }
            let mass = atomic_f32::load(&self.mass[node as usize]);
            let first = self.children.len() as u32;
            self.children[node as usize] = first;
            self.mass[node as usize] = atomic_f32::new(0.0);
            for index in 0..8 {
                self.children.push(0);
                self.mass.push(atomic_f32::new(mass / 8.0));
                if mass / 8.0 > threshold {
                    work.push((first + index, depth + 1));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deposits_land_in_the_leaf_that_holds_them_and_heavy_leaves_split() {
        let mut tree = FocalOctree::new(Vec3::ZERO, Vec3::ONE);
        tree.deposit(Vec3::splat(0.1), 3.0);
        tree.deposit(Vec3::splat(2.0), 5.0);
        assert_eq!(tree.leaves()[0].mass, 3.0, "outside the cube: nothing");
        tree.split_heavy_leaves(0.2, 1 << 10, 3);
        // 3 → eight of 0.375 → sixty-four of 0.047: two splits, 1 + 8 + 64 nodes.
        assert_eq!(tree.children.len(), 73);
        let leaves = tree.leaves();
        assert_eq!(leaves.len(), 64);
        let total: f32 = leaves.iter().map(|l| l.mass).sum();
        assert!((total - 3.0).abs() < 1e-5);
        let p = Vec3::new(0.9, 0.1, 0.6);
        let leaf = leaves.iter().find(|l| Some(l.node) == tree.leaf_at(p)).unwrap();
        assert!(p.cmpge(leaf.low).all() && p.cmplt(leaf.low + Vec3::splat(leaf.size)).all());
        assert_eq!(leaf.depth, 2);
    }

    #[test]
    fn a_segment_deposited_exactly_gives_each_leaf_its_length_inside() {
        let mut tree = FocalOctree::new(Vec3::ZERO, Vec3::ONE);
        tree.deposit(Vec3::splat(0.1), 1.0);
        tree.split_heavy_leaves(0.05, 1 << 10, 3);
        for leaf in tree.leaves() {
            tree.mass[leaf.node as usize] = atomic_f32::new(0.0);
        }
        // A diagonal-ish segment through the subdivided corner and beyond, weight 2.
        let origin = Vec3::new(0.02, 0.03, 0.05);
        let direction = Vec3::new(0.9, 0.3, 0.2).normalize();
        let length = 0.9;
        tree.deposit_along(origin, direction, (0.0, length), 2.0);
        let leaves = tree.leaves();
        let total: f32 = leaves.iter().map(|l| l.mass).sum();
        assert!((total - 2.0 * length).abs() < 1e-4, "{total}");
        for leaf in &leaves {
            let (near, far) =
                crate::focal::lanes::ray_box(origin, direction.recip(), leaf.low, leaf.low + Vec3::splat(leaf.size));
            let inside = (far.min(length) - near.max(0.0)).max(0.0);
            assert!((leaf.mass - 2.0 * inside).abs() < 1e-4, "leaf {}: {} against {}", leaf.node, leaf.mass, inside);
        }
        // Along an axis, starting on a leaf's face, and degenerate segments: no panic, no
        // mass lost.
        let before: f32 = tree.leaves().iter().map(|l| l.mass).sum();
        tree.deposit_along(Vec3::new(0.0, 0.25, 0.5), Vec3::X, (0.0, 1.0), 1.0);
        tree.deposit_along(Vec3::splat(0.5), Vec3::Y, (0.3, 0.3), 1.0);
        let after: f32 = tree.leaves().iter().map(|l| l.mass).sum();
        assert!((after - before - 1.0).abs() < 1e-4, "{before} → {after}");
    }
}
