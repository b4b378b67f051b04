//! The binary hierarchy as flat arrays a GPU traverses ([`flat_bvh2`]).
//!
//! Layout, for a shader's storage buffers:
//! - `nodes`: 32 bytes each, `min.xyz, first, max.xyz, count` (f32 ×3, u32, f32 ×3,
//!   u32). `count == 0`: an inner node whose children are `nodes[first]` and
//!   `nodes[first + 1]`. `count > 0`: a leaf holding triangles `first .. first + count`.
//!   The root is `nodes[0]`.
//! - `triangles`: the triangles in leaf order, world space.
//! - `original_index`: the index in the caller's slice of each of them.
//!
//! Bounds are inflated by 10⁻⁶ of the scene's size, as for the CPU hierarchies, so a
//! slab test that rounds the wrong way still visits every node a ray touches.

use glam::{Vec3, Vec3A};
use guiding_core::Triangle;
use obvhs::BvhBuildParams;

use crate::{InflatedBounds, BOUNDS_MARGIN};

/// One node of a [`FlatBvh`]; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct FlatBvhNode {
    /// Lower corner of the node's bounds.
    pub min: [f32; 3],
    /// First child (inner node) or first triangle (leaf).
    pub first: u32,
    /// Upper corner of the node's bounds.
    pub max: [f32; 3],
    /// Triangles in the leaf; 0 for an inner node.
    pub count: u32,
}

/// A binary BVH in flat arrays; see the module documentation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FlatBvh {
    /// Nodes, root first.
    pub nodes: Vec<FlatBvhNode>,
    /// Triangles in leaf order.
    pub triangles: Vec<[Vec3; 3]>,
    /// Index in the caller's slice of each triangle.
    pub original_index: Vec<u32>,
}

/// Builds obvhs's BVH2 (PLOC with reinsertion) over the finite `triangles` and flattens
/// it; no nodes for no finite triangle.
pub fn flat_bvh2(triangles: &[Triangle]) -> FlatBvh {
    let kept: Vec<u32> = (0..triangles.len() as u32).filter(|&i| triangles[i as usize].is_finite()).collect();
    if kept.is_empty() {
        return FlatBvh::default();
    }
    let (low, high) = kept
        .iter()
        .flat_map(|&i| triangles[i as usize].vertices)
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), v| (low.min(v), high.max(v)));
    let size = (high - low).length() + low.abs().max(high.abs()).max_element();
    let margin = Vec3A::splat(BOUNDS_MARGIN * size);
    let bounds: Vec<InflatedBounds> = kept
        .iter()
        .map(|&i| {
            let [v0, v1, v2] = triangles[i as usize].vertices.map(Vec3A::from);
            InflatedBounds { min: v0.min(v1).min(v2) - margin, max: v0.max(v1).max(v2) + margin }
        })
        .collect();
    let mut build_time = std::time::Duration::default();
    let bvh = obvhs::bvh2::builder::build_bvh2(&bounds, BvhBuildParams::medium_build(), &mut build_time);
    let nodes = bvh
        .nodes
        .iter()
        .map(|node| FlatBvhNode {
            min: Vec3::from(node.aabb.min).to_array(),
            first: node.first_index,
            max: Vec3::from(node.aabb.max).to_array(),
            count: node.prim_count,
        })
        .collect();
    let original_index: Vec<u32> = bvh.primitive_indices.iter().map(|&p| kept[p as usize]).collect();
    let triangles = original_index.iter().map(|&i| triangles[i as usize].vertices).collect();
    FlatBvh { nodes, triangles, original_index }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle sits in exactly one leaf, inside the bounds of every node above it.
    #[test]
    fn leaves_cover_every_triangle_inside_their_ancestors() {
        let mut rng = guiding_core::Pcg32::new(5, 5);
        let mut triangles = Vec::new();
        for _ in 0..500 {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
            let jitter = |rng: &mut guiding_core::Pcg32| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            triangles.push(Triangle::new(p, p + jitter(&mut rng), p + jitter(&mut rng)));
        }
        triangles.push(Triangle::new(Vec3::NAN, Vec3::ZERO, Vec3::X));
        let flat = flat_bvh2(&triangles);
        assert_eq!(flat.triangles.len(), 500, "the non-finite triangle is left out");
        let mut seen = vec![0u32; 501];
        let mut stack = vec![(0usize, Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY))];
        while let Some((index, lo, hi)) = stack.pop() {
            let node = flat.nodes[index];
            let (min, max) = (Vec3::from(node.min), Vec3::from(node.max));
            assert!(min.cmpge(lo).all() && max.cmple(hi).all(), "node {index} leaves its parent");
            if node.count == 0 {
                stack.push((node.first as usize, min, max));
                stack.push((node.first as usize + 1, min, max));
            } else {
                for slot in node.first..node.first + node.count {
                    let [a, b, c] = flat.triangles[slot as usize];
                    for v in [a, b, c] {
                        assert!(v.cmpge(min).all() && v.cmple(max).all());
                    }
                    seen[flat.original_index[slot as usize] as usize] += 1;
                }
            }
        }
        assert!(seen[..500].iter().all(|&n| n == 1) && seen[500] == 0);
    }
}
