//! The byte image of a [`SpatialDirectionalTree`] and the checks every loaded (or
//! learned) tree must pass.
//!
//! ```text
//! "LODESTAR" · u32 version · u32 tag 4
//! settings: u64 budget · f32 c · u32 min split records · f32 mixed normal share · f32 ρ
//!           · u32 directional depth
//!           · u32 spatial depth · f32 uniform mix · u32 fold · u32 cosine product
//!           · u32 trees per axis · u32 second moment · update rule (12 bytes)
//! vec3 low · vec3 extent · u32 epoch · u64 records before · u32 rejected NaN/∞ · u32 rejected < 0
//! u32 spatial root × (3 with trees per axis, else 1) · u32 spatial nodes · u32 leaves
//! · u32 directional nodes
//! spatial node × n: u32 low child · u32 high child · u32 axis
//! leaf × n: u32 root · f32 flux · u64 weight (f64 bits) · u32 parent (node·2 + side, or
//!           u32::MAX − t at the root of spatial tree t) · vec3 extent · u32 depth · u32 axis (0, 1, 2) · this epoch's
//!           counts: per half, u32 records and u32 normals along x, y, z
//! directional node × n: f32 probability × 4 · u32 child × 4 · f32 building sum × 4
//! u64 FNV-1a checksum
//! ```

use alloc::vec::Vec;
use core::sync::atomic::{AtomicU32, Ordering};

use super::axis::LeafCounts;
use super::guide::{SpatialDirectionalTree, SpatialLeaf};
use super::quadtree::QuadNode;
use super::settings::{SpatialDirectionalTreeSettings, MAX_SPATIAL_DEPTH};
use super::spatial::{Parent, SpatialNode, LEAF};
use crate::atomic_f32;
use crate::bytes::{invalid_field, open_guide_bytes, ByteWriter};
use crate::error::Error;

/// Version of the byte format.
pub const FORMAT_VERSION: u32 = 5;
/// Structure tag of a spatial × directional tree.
pub const STRUCTURE_TAG: u32 = 4;

const SPATIAL_NODE_SIZE: usize = 12;
const LEAF_SIZE: usize = 72;
const QUAD_NODE_SIZE: usize = 48;
/// A root leaf's parent code is this minus its spatial tree's index.
const NO_PARENT: u32 = u32::MAX;
/// Most spatial trees a tree holds (one per world axis).
const MAX_TREES: u32 = 3;

pub(crate) fn to_bytes(tree: &SpatialDirectionalTree) -> Vec<u8> {
    let size =
        128 + tree.spatial.len() * SPATIAL_NODE_SIZE + tree.leaves.len() * LEAF_SIZE + tree.quad.len() * QUAD_NODE_SIZE;
    let mut w = ByteWriter::with_capacity(size);
    w.put_header(FORMAT_VERSION, STRUCTURE_TAG);
    let s = &tree.settings;
    w.put_u64(s.budget_bytes as u64);
    w.put_f32(s.spatial_threshold);
    w.put_u32(s.min_split_records);
    w.put_f32(s.mixed_normal_share);
    w.put_f32(s.flux_fraction);
    w.put_u32(s.max_directional_depth);
    w.put_u32(s.max_spatial_depth);
    w.put_f32(s.uniform_mix);
    w.put_u32(s.fold_to_hemisphere as u32);
    w.put_u32(s.cosine_product as u32);
    w.put_u32(s.trees_per_axis as u32);
    w.put_u32(s.second_moment as u32);
    w.put_update_rule(&s.update_rule);
    for v in [tree.low, tree.extent] {
        v.to_array().into_iter().for_each(|c| w.put_f32(c));
    }
    w.put_u32(tree.epoch);
    w.put_u64(tree.accepted_before);
    w.put_u32(tree.rejected_non_finite.load(Ordering::Relaxed));
    w.put_u32(tree.rejected_negative.load(Ordering::Relaxed));
    tree.spatial_roots.iter().for_each(|&root| w.put_u32(root));
    w.put_u32(tree.spatial.len() as u32);
    w.put_u32(tree.leaves.len() as u32);
    w.put_u32(tree.quad.len() as u32);
    for node in &tree.spatial {
        w.put_u32(node.child[0]);
        w.put_u32(node.child[1]);
        w.put_u32(node.axis);
    }
    for (leaf, counts) in tree.leaves.iter().zip(&tree.leaf_counts) {
        w.put_u32(leaf.root);
        w.put_f32(leaf.flux);
        w.put_u64(leaf.weight.to_bits());
        w.put_u32(match leaf.parent {
            Parent::Root { tree } => NO_PARENT - tree,
            Parent::Node { node, side } => node * 2 + side,
        });
        leaf.extent.to_array().into_iter().for_each(|c| w.put_f32(c));
        w.put_u32(leaf.depth);
        w.put_u32(leaf.axis);
        counts.values().into_iter().for_each(|c| w.put_u32(c));
    }
    for (index, node) in tree.quad.iter().enumerate() {
        node.probability.iter().for_each(|&p| w.put_f32(p));
        node.child.iter().for_each(|&c| w.put_u32(c));
        tree.sums[index * 4..index * 4 + 4].iter().for_each(|s| w.put_f32(atomic_f32::load(s)));
    }
    w.finish_with_checksum()
}

pub(crate) fn from_bytes(bytes: &[u8]) -> Result<SpatialDirectionalTree, Error> {
    let mut r = open_guide_bytes(bytes, FORMAT_VERSION, STRUCTURE_TAG)?;
    let budget_bytes = r.u64()?;
    let settings = SpatialDirectionalTreeSettings {
        budget_bytes: usize::try_from(budget_bytes).map_err(|_| invalid_field("budget_bytes", 0, "fits in usize"))?,
        spatial_threshold: r.f32()?,
        min_split_records: r.u32()?,
        mixed_normal_share: r.f32()?,
        flux_fraction: r.f32()?,
        max_directional_depth: r.u32()?,
        max_spatial_depth: r.u32()?,
        uniform_mix: r.f32()?,
        fold_to_hemisphere: r.flag("fold_to_hemisphere")?,
        cosine_product: r.flag("cosine_product")?,
        trees_per_axis: r.flag("trees_per_axis")?,
        second_moment: r.flag("second_moment")?,
        update_rule: r.update_rule()?,
    };
    settings.validate()?;
    let (low, extent) = (r.vec3()?, r.vec3()?);
    let epoch = r.u32()?;
    let accepted_before = r.u64()?;
    let (rejected_non_finite, rejected_negative) = (r.u32()?, r.u32()?);
    let mut spatial_roots = Vec::with_capacity(settings.spatial_tree_count());
    for _ in 0..settings.spatial_tree_count() {
        spatial_roots.push(r.u32()?);
    }
    let counts = [r.u32()? as usize, r.u32()? as usize, r.u32()? as usize];
    // Check the length before allocating, so a damaged count cannot demand memory.
    let needed = counts[0] as u64 * SPATIAL_NODE_SIZE as u64
        + counts[1] as u64 * LEAF_SIZE as u64
        + counts[2] as u64 * QUAD_NODE_SIZE as u64;
    r.expect_remaining(usize::try_from(needed).unwrap_or(usize::MAX))?;
    let mut spatial = Vec::with_capacity(counts[0]);
    for _ in 0..counts[0] {
        spatial.push(SpatialNode { child: [r.u32()?, r.u32()?], axis: r.u32()? });
    }
    let (mut leaves, mut leaf_counts) = (Vec::with_capacity(counts[1]), Vec::with_capacity(counts[1]));
    for index in 0..counts[1] {
        let root = r.u32()?;
        let flux = r.f32()?;
        let weight = f64::from_bits(r.u64()?);
        let parent = match r.u32()? {
            code if code > NO_PARENT - MAX_TREES => Parent::Root { tree: NO_PARENT - code },
            code => Parent::Node { node: code / 2, side: code % 2 },
        };
        let extent = r.vec3()?;
        let depth = r.u32()?;
        if depth > MAX_SPATIAL_DEPTH {
            return Err(invalid_field("leaf.depth", index, "at most 24"));
        }
        let axis = r.u32()?;
        if axis > 2 {
            return Err(invalid_field("leaf.axis", index, "0, 1 or 2"));
        }
        leaves.push(SpatialLeaf { root, flux, weight, parent, extent, depth, axis });
        let mut values = [0u32; 8];
        for value in &mut values {
            *value = r.u32()?;
        }
        let Some(leaf_count) = LeafCounts::from_values(values) else {
            return Err(invalid_field(
                "leaf.counts",
                index,
                "per half, x, y and z votes adding up to at most the records",
            ));
        };
        leaf_counts.push(leaf_count);
    }
    let (mut quad, mut sums) = (Vec::with_capacity(counts[2]), Vec::with_capacity(counts[2] * 4));
    for _ in 0..counts[2] {
        let probability = [r.f32()?, r.f32()?, r.f32()?, r.f32()?];
        let child = [r.u32()?, r.u32()?, r.u32()?, r.u32()?];
        quad.push(QuadNode { probability, child });
        for _ in 0..4 {
            sums.push(atomic_f32::new(r.f32()?));
        }
    }
    r.finish()?;
    let mut tree = SpatialDirectionalTree {
        settings,
        low,
        extent,
        inverse_extent: extent.recip(),
        spatial_roots,
        spatial,
        leaves,
        leaf_counts,
        quad,
        sums,
        cosine: Vec::new(),
        top: Default::default(),
        epoch,
        accepted_before,
        rejected_non_finite: AtomicU32::new(rejected_non_finite),
        rejected_negative: AtomicU32::new(rejected_negative),
    };
    validate(&tree)?;
    tree.refresh_derived();
    Ok(tree)
}

/// Checks the tree's structure and values: every node and leaf reached exactly once
/// from its root, depths within the settings, probabilities normalised, sums and
/// fluxes finite and non-negative, memory within the budget.
pub(crate) fn validate(tree: &SpatialDirectionalTree) -> Result<(), Error> {
    tree.settings.validate()?;
    let finite_positive = |v: glam::Vec3| v.is_finite() && v.min_element() > 0.0;
    if !(tree.low.is_finite() && finite_positive(tree.extent)) {
        return Err(invalid_field("bounds", 0, "a finite low corner and a positive extent"));
    }
    if tree.leaves.is_empty() || tree.quad.is_empty() {
        return Err(invalid_field("leaves", 0, "at least one leaf and one directional node"));
    }
    if tree.sums.len() != tree.quad.len() * 4 || tree.leaf_counts.len() != tree.leaves.len() {
        return Err(invalid_field("building_sums", 0, "four per directional node, one set of counts per leaf"));
    }
    if tree.memory_bytes() > tree.settings.budget_bytes {
        return Err(invalid_field("budget_bytes", 0, "at least the memory the tree holds"));
    }
    check_spatial(tree)?;
    let mut seen = alloc::vec![false; tree.quad.len()];
    for (index, leaf) in tree.leaves.iter().enumerate() {
        if !(leaf.flux.is_finite() && leaf.flux >= 0.0) {
            return Err(invalid_field("leaf.flux", index, "finite and ≥ 0"));
        }
        if !(leaf.weight.is_finite() && leaf.weight >= 0.0) {
            return Err(invalid_field("leaf.weight", index, "finite and ≥ 0"));
        }
        if !finite_positive(leaf.extent) {
            return Err(invalid_field("leaf.extent", index, "finite and > 0"));
        }
        if leaf.axis > 2 {
            return Err(invalid_field("leaf.axis", index, "0, 1 or 2"));
        }
        check_quadtree(tree, leaf.root, &mut seen)?;
    }
    if let Some(orphan) = seen.iter().position(|&s| !s) {
        return Err(invalid_field("directional_node", orphan, "reachable from a leaf's root"));
    }
    if let Some(bad) = tree.sums.iter().position(|s| !(atomic_f32::load(s) >= 0.0 && atomic_f32::load(s).is_finite())) {
        return Err(invalid_field("building_sums", bad, "finite and ≥ 0"));
    }
    Ok(())
}

fn check_spatial(tree: &SpatialDirectionalTree) -> Result<(), Error> {
    let mut node_seen = alloc::vec![false; tree.spatial.len()];
    let mut leaf_seen = alloc::vec![false; tree.leaves.len()];
    if tree.spatial_roots.len() != tree.settings.spatial_tree_count() {
        return Err(invalid_field("spatial_roots", 0, "one per spatial tree the settings keep"));
    }
    // (reference, depth, where it hangs, which spatial tree)
    let roots = tree.spatial_roots.iter().enumerate();
    let mut stack: Vec<(u32, u32, Parent, u32)> =
        roots.map(|(t, &root)| (root, 0u32, Parent::Root { tree: t as u32 }, t as u32)).collect();
    while let Some((reference, depth, parent, spatial_tree)) = stack.pop() {
        if reference & LEAF != 0 {
            let leaf = (reference & !LEAF) as usize;
            if leaf >= tree.leaves.len() || leaf_seen[leaf] {
                return Err(invalid_field("spatial_node.child", leaf, "each leaf named once"));
            }
            leaf_seen[leaf] = true;
            if tree.leaves[leaf].parent != parent || tree.leaves[leaf].depth != depth {
                return Err(invalid_field("leaf.parent", leaf, "where the tree holds it, at its depth"));
            }
            if tree.settings.trees_per_axis && tree.leaves[leaf].axis != spatial_tree {
                return Err(invalid_field("leaf.axis", leaf, "the axis of the spatial tree holding it"));
            }
            continue;
        }
        let node = reference as usize;
        if node >= tree.spatial.len() || node_seen[node] || depth > tree.settings.max_spatial_depth.max(1) {
            return Err(invalid_field("spatial_node", node, "each node named once, within the depth limit"));
        }
        node_seen[node] = true;
        if tree.spatial[node].axis > 2 {
            return Err(invalid_field("spatial_node.axis", node, "0, 1 or 2"));
        }
        for side in 0..2 {
            stack.push((
                tree.spatial[node].child[side],
                depth + 1,
                Parent::Node { node: node as u32, side: side as u32 },
                spatial_tree,
            ));
        }
    }
    if let Some(node) = node_seen.iter().position(|&s| !s) {
        return Err(invalid_field("spatial_node", node, "reachable from a root"));
    }
    if let Some(leaf) = leaf_seen.iter().position(|&s| !s) {
        return Err(invalid_field("leaf", leaf, "reachable from a root"));
    }
    Ok(())
}

fn check_quadtree(tree: &SpatialDirectionalTree, root: u32, seen: &mut [bool]) -> Result<(), Error> {
    let mut stack = alloc::vec![(root, 1u32)];
    while let Some((node, depth)) = stack.pop() {
        let index = node as usize;
        if index >= tree.quad.len() || seen[index] || depth > tree.settings.max_directional_depth {
            return Err(invalid_field("directional_node", index, "each node named once, within the depth limit"));
        }
        seen[index] = true;
        let n = &tree.quad[index];
        let sum: f32 = n.probability.iter().sum();
        if !n.probability.iter().all(|p| (0.0..=1.0).contains(p)) || (sum - 1.0).abs() > 1e-3 {
            return Err(invalid_field("directional_node.probability", index, "in [0, 1], summing to 1"));
        }
        for &child in &n.child {
            if child != 0 {
                stack.push((child, depth + 1));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;
    use glam::Vec3;

    fn learned() -> SpatialDirectionalTree {
        let settings = SpatialDirectionalTreeSettings { min_split_records: 100, ..Default::default() };
        let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
        let mut rng = Pcg32::new(2, 2);
        for _ in 0..3 {
            for _ in 0..20_000 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let region = tree.locate(p, Vec3::Y).unwrap();
                let s = tree.sample(region, rng.next_vec2());
                tree.update_sampled(region, s.direction, s.direction.x.max(0.0) * 10.0, s.pdf);
            }
            tree.rebuild_sampling();
        }
        let region = tree.locate(Vec3::ZERO, Vec3::Y).unwrap();
        tree.update(region, Vec3::X, 3.0);
        tree
    }

    #[test]
    fn round_trip_keeps_everything_and_damage_is_named() {
        let tree = learned();
        assert!(tree.leaf_count() > 1 && tree.directional_node_count() > tree.leaf_count());
        let bytes = tree.to_bytes();
        let loaded = SpatialDirectionalTree::from_bytes(&bytes).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        assert_eq!(tree.clone().to_bytes(), bytes);
        assert_eq!(loaded.stats(), tree.stats());
        // A child pointing back at a root is a cycle the checks must catch.
        let mut cyclic = tree.clone();
        let root = cyclic.leaves[0].root;
        cyclic.quad[root as usize].child[0] = cyclic.leaves[cyclic.leaves.len() - 1].root;
        assert!(SpatialDirectionalTree::from_bytes(&cyclic.to_bytes()).is_err());
        let mut short = bytes.clone();
        short.truncate(bytes.len() - 20);
        assert!(SpatialDirectionalTree::from_bytes(&short).is_err());
    }

    /// A tree per axis, learned on a corner (floor, wall and a slope), round-trips, merges
    /// with a copy of itself, and a root leaf named under another tree's root is refused.
    #[test]
    fn trees_per_axis_round_trip_merge_and_name_a_misplaced_root() {
        let settings =
            SpatialDirectionalTreeSettings { min_split_records: 100, trees_per_axis: true, ..Default::default() };
        let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
        let mut rng = Pcg32::new(3, 3);
        let normals = [Vec3::Y, -Vec3::X, Vec3::new(0.0, 0.6, 0.8)];
        for _ in 0..3 {
            for i in 0..30_000 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let region = tree.locate(p, normals[i % 3]).unwrap();
                let s = tree.sample(region, rng.next_vec2());
                tree.update_sampled(region, s.direction, s.direction.x.max(0.0) * 10.0, s.pdf);
            }
            tree.rebuild_sampling();
        }
        assert!(tree.leaf_count() > 3);
        let axes: Vec<u32> = (0..tree.leaf_count() as u32).filter_map(|l| tree.leaf_axis(l)).collect();
        assert!((0..3).all(|a| axes.contains(&a)), "every tree learned: {axes:?}");
        let bytes = tree.to_bytes();
        let loaded = SpatialDirectionalTree::from_bytes(&bytes).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        let mut merged = tree.clone();
        merged.merge(&loaded).unwrap();
        merged.validate().unwrap();
        assert_eq!(merged.leaf_count(), tree.leaf_count());
        // Two trees' roots swapped: each root leaf then hangs where the bytes say it
        // does not.
        let mut swapped = tree.clone();
        swapped.spatial_roots.swap(0, 1);
        assert!(SpatialDirectionalTree::from_bytes(&swapped.to_bytes()).is_err());
        // The byte image of a single tree does not load as one per axis.
        let mut single = tree.clone();
        single.settings.trees_per_axis = false;
        assert!(SpatialDirectionalTree::from_bytes(&single.to_bytes()).is_err());
    }
}
