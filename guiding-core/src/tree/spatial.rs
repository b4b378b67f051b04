//! The spatial half of the tree: a binary tree over the scene's box whose nodes halve
//! their box along one axis, found by one descent from the root (no neighbour search).

use alloc::vec::Vec;

use glam::Vec3;

use super::square::ONE_BELOW;

/// Marks a child reference as a leaf index rather than a node index.
pub(crate) const LEAF: u32 = 1 << 31;

/// An inner node: its two halves along `axis` (low first), each a node index or
/// `LEAF | leaf index`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SpatialNode {
    /// The halves.
    pub(crate) child: [u32; 2],
    /// 0, 1 or 2 for x, y, z.
    pub(crate) axis: u32,
}

/// Bytes one inner node costs.
pub(crate) const SPATIAL_NODE_BYTES: usize = core::mem::size_of::<SpatialNode>();

/// `position` (scene units) in the box's unit cube, given the box's low corner and the
/// reciprocal of its extent, clamped into [0, 1) (points outside belong to the nearest
/// leaf); `None` for a non-finite position.
#[inline]
pub(crate) fn unit_position(low: Vec3, inverse_extent: Vec3, position: Vec3) -> Option<Vec3> {
    let p = (position - low) * inverse_extent;
    p.is_finite().then(|| p.clamp(Vec3::ZERO, Vec3::splat(ONE_BELOW)))
}

/// The leaf below the node `reference` (a node index, or `LEAF | leaf`) holding `p`,
/// given in that node's unit cube, and `p` in the leaf's unit cube.
#[inline]
pub(crate) fn descend_to_leaf(nodes: &[SpatialNode], mut reference: u32, mut p: Vec3) -> (u32, Vec3) {
    while reference & LEAF == 0 {
        let node = &nodes[reference as usize];
        // Selects, not an indexed store and load: the point stays in registers.
        let (on_x, on_y) = (node.axis == 0, node.axis == 1);
        let coordinate = if on_x {
            p.x
        } else if on_y {
            p.y
        } else {
            p.z
        };
        // Doubling and subtracting one are exact: the point stays in its half's unit box.
        let x = coordinate * 2.0;
        let high = x >= 1.0;
        let moved = if high { x - 1.0 } else { x };
        p = Vec3::new(
            if on_x { moved } else { p.x },
            if on_y { moved } else { p.y },
            if on_x || on_y { p.z } else { moved },
        );
        reference = node.child[high as usize];
    }
    (reference & !LEAF, p)
}

/// Where a leaf hangs: the node and side whose child reference names it, or the root.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Parent {
    /// Spatial tree `tree` (of the settings' [`spatial_tree_count`]) is this one leaf.
    ///
    /// [`spatial_tree_count`]: super::SpatialDirectionalTreeSettings::spatial_tree_count
    Root {
        /// Which of the spatial trees.
        tree: u32,
    },
    /// `nodes[node].child[side]`.
    Node {
        /// Node index.
        node: u32,
        /// 0 for the low half, 1 for the high half.
        side: u32,
    },
}

/// Splits the leaf `leaf` hanging at `parent` along `axis`: a new node takes its place,
/// with `leaf` as the low half and `new_leaf` as the high half. Returns the new node's
/// index; `roots` (the spatial trees' roots) is updated when the leaf was a root.
pub(crate) fn split_leaf(
    nodes: &mut Vec<SpatialNode>,
    roots: &mut [u32],
    parent: Parent,
    leaf: u32,
    new_leaf: u32,
    axis: u32,
) -> u32 {
    let index = nodes.len() as u32;
    nodes.push(SpatialNode { child: [LEAF | leaf, LEAF | new_leaf], axis });
    match parent {
        Parent::Root { tree } => {
            if let Some(root) = roots.get_mut(tree as usize) {
                *root = index;
            }
        }
        Parent::Node { node, side } => nodes[node as usize].child[side as usize] = index,
    }
    index
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn descent_finds_the_half_a_point_lies_in() {
        let mut nodes = Vec::new();
        let mut roots = [LEAF];
        let first = split_leaf(&mut nodes, &mut roots, Parent::Root { tree: 0 }, 0, 1, 0);
        split_leaf(&mut nodes, &mut roots, Parent::Node { node: first, side: 1 }, 1, 2, 1);
        let root = roots[0];
        let (low, inverse) = (Vec3::splat(-1.0), Vec3::splat(0.5));
        let at = |x: f32, y: f32| {
            unit_position(low, inverse, Vec3::new(x, y, 0.0)).map(|p| descend_to_leaf(&nodes, root, p).0)
        };
        assert_eq!(at(-0.5, 0.7), Some(0));
        assert_eq!(at(0.5, -0.7), Some(1));
        assert_eq!(at(0.5, 0.7), Some(2));
        assert_eq!(at(9.0, 9.0), Some(2), "outside points clamp to the box");
        assert_eq!(at(f32::NAN, 0.0), None);
    }
}
