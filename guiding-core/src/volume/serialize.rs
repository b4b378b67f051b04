//! The byte format of an [`IrradianceVolume`] (version 1, little-endian).
//!
//! ```text
//! "LODESTAR" magic (8 bytes) · u32 format version · u32 structure tag (2)
//! settings: u64 budget · f32 initial_share · u32 resolution given (0/1) · u32×3 resolution
//!           · u32 nz · u32 nφ · f32 split_updates_per_patch · f32 initial_q · f32 q_floor
//!           · f32 uniform_mix · u32 learning-rate kind · f32 its parameter
//!           · u32 integral estimator
//! state:    f32×3 low · f32×3 high · u32×3 grid resolution · u32 epoch
//!           · u64 rejected non-finite · u64 rejected negative · u32 node count M
//!           · u32 leaf count L · M u32 nodes (bit 31: leaf, else first child)
//!           · L u32 leaf visits · L·N f32 Q · L·N u32 patch visits · L·N f32 CDF
//!           · L×9 f32 spherical-harmonic coefficients
//! u64 FNV-1a checksum of everything before it
//! ```

use alloc::vec;
use alloc::vec::Vec;

use crate::bytes::{invalid_field, open_guide_bytes, ByteReader, ByteWriter};
use crate::error::{DecodeError, Error};

use super::guide::{IrradianceVolume, VolumeState, LEAF};
use super::settings::IrradianceVolumeSettings;
use super::sphere_layout::SphereLayout;

/// Format version written and read by this build.
pub const FORMAT_VERSION: u32 = 1;
/// Structure tag of an irradiance volume.
pub const STRUCTURE_TAG: u32 = 2;

pub(crate) fn encode(volume: &IrradianceVolume) -> Vec<u8> {
    let s = volume.settings();
    let state = volume.state();
    let mut w = ByteWriter::with_capacity(160 + state.nodes.len() * 4 + state.q.len() * 12);
    w.put_header(FORMAT_VERSION, STRUCTURE_TAG);
    w.put_u64(s.budget_bytes as u64);
    w.put_f32(s.initial_share);
    w.put_u32(s.resolution.is_some() as u32);
    s.resolution.unwrap_or([0; 3]).iter().for_each(|&n| w.put_u32(n));
    s.layout.resolution.iter().for_each(|&n| w.put_u32(n));
    for v in [s.split_updates_per_patch, s.initial_q, s.q_floor, s.uniform_mix] {
        w.put_f32(v);
    }
    w.put_update_rule(&s.update_rule);
    let (low, high) = volume.bounds();
    low.to_array().iter().chain(&high.to_array()).for_each(|&c| w.put_f32(c));
    volume.resolution().iter().for_each(|&n| w.put_u32(n));
    w.put_u32(state.epoch);
    w.put_u64(state.rejected_non_finite as u64);
    w.put_u64(state.rejected_negative as u64);
    w.put_u32(state.nodes.len() as u32);
    w.put_u32(state.leaf_visits.len() as u32);
    state.nodes.iter().chain(&state.leaf_visits).for_each(|&v| w.put_u32(v));
    state.q.iter().for_each(|&q| w.put_f32(q));
    state.patch_visits.iter().for_each(|&v| w.put_u32(v));
    state.cdf.iter().for_each(|&c| w.put_f32(c));
    state.irradiance.iter().flatten().for_each(|&c| w.put_f32(c));
    w.finish_with_checksum()
}

fn read_settings(r: &mut ByteReader<'_>) -> Result<IrradianceVolumeSettings, Error> {
    let budget_bytes = usize::try_from(r.u64()?).map_err(|_| invalid_field("budget_bytes", 0, "addressable"))?;
    let initial_share = r.f32()?;
    let given = r.flag("resolution_given")?;
    let resolution = [r.u32()?, r.u32()?, r.u32()?];
    let layout = SphereLayout { resolution: [r.u32()?, r.u32()?] };
    let (split_updates_per_patch, initial_q, q_floor, uniform_mix) = (r.f32()?, r.f32()?, r.f32()?, r.f32()?);
    let settings = IrradianceVolumeSettings {
        budget_bytes,
        initial_share,
        resolution: given.then_some(resolution),
        layout,
        split_updates_per_patch,
        initial_q,
        q_floor,
        uniform_mix,
        update_rule: r.update_rule()?,
    };
    settings.validate()?;
    Ok(settings)
}

/// Checks the tree: the first `roots` nodes are the grid's cells; every internal node's
/// eight children lie after it and inside the array; every node but the roots is some
/// node's child exactly once; every leaf index is below `leaves` and used exactly once.
pub(crate) fn check_tree(nodes: &[u32], roots: usize, leaves: usize) -> Result<(), Error> {
    if nodes.len() < roots || (nodes.len() - roots) % 8 != 0 {
        return Err(invalid_field("nodes", 0, "the grid's cells plus eight per split"));
    }
    let mut parented = vec![false; nodes.len()];
    let mut leaf_used = vec![false; leaves];
    for (index, &entry) in nodes.iter().enumerate() {
        if index >= roots && !parented[index] {
            return Err(invalid_field("nodes", index, "every node below the grid is some node's child"));
        }
        if entry & LEAF != 0 {
            let leaf = (entry & !LEAF) as usize;
            if leaf >= leaves || core::mem::replace(&mut leaf_used[leaf], true) {
                return Err(invalid_field("nodes", index, "leaf indices below the leaf count, each used once"));
            }
        } else {
            let first = entry as usize;
            if first <= index || first < roots || first + 8 > nodes.len() || (first - roots) % 8 != 0 {
                return Err(invalid_field("nodes", index, "children after their parent, eight in a row"));
            }
            for seen in &mut parented[first..first + 8] {
                if core::mem::replace(seen, true) {
                    return Err(invalid_field("nodes", index, "each node the child of one parent"));
                }
            }
        }
    }
    if let Some(leaf) = leaf_used.iter().position(|&used| !used) {
        return Err(invalid_field("leaf_count", leaf, "every leaf in the tree"));
    }
    Ok(())
}

fn read_u32s(r: &mut ByteReader<'_>, count: usize) -> Result<Vec<u32>, DecodeError> {
    (0..count).map(|_| r.u32()).collect()
}

fn read_f32s(r: &mut ByteReader<'_>, count: usize) -> Result<Vec<f32>, DecodeError> {
    (0..count).map(|_| r.f32()).collect()
}

pub(crate) fn decode(bytes: &[u8]) -> Result<IrradianceVolume, Error> {
    let mut r = open_guide_bytes(bytes, FORMAT_VERSION, STRUCTURE_TAG)?;
    let settings = read_settings(&mut r)?;
    let (low, high) = (r.vec3()?, r.vec3()?);
    let resolution = [r.u32()?, r.u32()?, r.u32()?];
    let epoch = r.u32()?;
    let (rejected_non_finite, rejected_negative) = (r.u64()? as usize, r.u64()? as usize);
    let (node_count, leaf_count) = (r.u32()? as usize, r.u32()? as usize);
    let grid = IrradianceVolume::grid_for(low, high, &settings)?;
    if grid.resolution() != resolution {
        return Err(invalid_field("grid_resolution", 0, "the resolution the settings give"));
    }
    let patches = settings.layout.patch_count();
    // Check the length before allocating, so a damaged count cannot demand memory.
    let needed = node_count
        .checked_add(leaf_count)
        .and_then(|words| leaf_count.checked_mul(3 * patches + 9).and_then(|table| table.checked_add(words)))
        .and_then(|words| words.checked_mul(4))
        .ok_or_else(|| invalid_field("node_count", 0, "addressable"))?;
    r.expect_remaining(needed)?;
    let nodes = read_u32s(&mut r, node_count)?;
    check_tree(&nodes, grid.cell_count(), leaf_count)?;
    let leaf_visits = read_u32s(&mut r, leaf_count)?;
    let q = read_f32s(&mut r, leaf_count * patches)?;
    if let Some(i) = q.iter().position(|&q| !(q.is_finite() && q >= settings.q_floor)) {
        return Err(invalid_field("q", i, "finite and at least q_floor"));
    }
    let patch_visits = read_u32s(&mut r, leaf_count * patches)?;
    let cdf = read_f32s(&mut r, leaf_count * patches)?;
    crate::table_checks::check_cdf_rows(&cdf, patches)?;
    let coefficients = read_f32s(&mut r, leaf_count * 9)?;
    if let Some(i) = coefficients.iter().position(|c| !c.is_finite()) {
        return Err(invalid_field("irradiance", i, "finite"));
    }
    let irradiance = coefficients.chunks_exact(9).map(|c| core::array::from_fn(|i| c[i])).collect();
    r.finish()?;
    let volume = IrradianceVolume::assemble(
        low,
        high,
        settings,
        grid,
        VolumeState {
            nodes,
            q,
            patch_visits,
            leaf_visits,
            cdf,
            irradiance,
            epoch,
            rejected_non_finite,
            rejected_negative,
        },
    );
    if volume.memory_bytes() > settings.budget_bytes {
        return Err(invalid_field("node_count", 0, "a tree within the byte budget"));
    }
    Ok(volume)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guide::Guide;
    use glam::Vec3;

    #[test]
    fn round_trip_after_splits_and_broken_trees_are_rejected() {
        let settings = IrradianceVolumeSettings { budget_bytes: 120 << 10, ..Default::default() };
        let mut volume = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).unwrap();
        let region = volume.locate(Vec3::splat(0.1), Vec3::Y).unwrap();
        for i in 0..40_000 {
            let d = Vec3::new((i % 7) as f32 - 3.0, 1.0, (i % 5) as f32 - 2.0).normalize();
            volume.update(region, d, 1.0);
        }
        volume.rebuild_sampling();
        assert!(volume.node_count() > volume.resolution().iter().product::<u32>() as usize);
        let bytes = volume.to_bytes();
        let loaded = IrradianceVolume::from_bytes(&bytes).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        assert_eq!(loaded.stats(), volume.stats());
        let roots = volume.resolution().iter().product::<u32>() as usize;
        let mut nodes = volume.state().nodes;
        let leaves = volume.leaf_count();
        assert!(check_tree(&nodes, roots, leaves).is_ok());
        // A child pointing back up, a leaf used twice, a missing leaf.
        let internal = nodes.iter().position(|&e| e & LEAF == 0).unwrap();
        let saved = nodes[internal];
        nodes[internal] = 0;
        assert!(check_tree(&nodes, roots, leaves).is_err());
        nodes[internal] = saved;
        let last = nodes.len() - 1;
        nodes[last] = nodes[last - 1];
        assert!(check_tree(&nodes, roots, leaves).is_err());
        assert!(check_tree(&volume.state().nodes, roots, leaves + 1).is_err());
    }
}
