//! The byte format of a [`GaussianMixture`] (version 1, little-endian).
//!
//! ```text
//! "LODESTAR" magic (8 bytes) · u32 format version · u32 structure tag (3)
//! settings: u64 budget · u32 resolution given (0/1) · u32×3 resolution · u32 lobes K
//!           · u32 split_by_normal · f32 initial_q · f32 uniform_mix
//!           · u32 learning-rate kind · f32 its parameter · u32 integral estimator
//! state:    f32×3 low · f32×3 high · u32×3 grid resolution · u32 epoch
//!           · u64 rejected non-finite · u64 rejected negative · u32 region count R
//!           · R × (u32 observations · K × (f32×3 mean · f32 κ · f32 weight · f32 S0
//!             · f32×3 S1) · u32 batch count · K × f32×4 batch sums)
//! u64 FNV-1a checksum of everything before it
//! ```
//!
//! The pending batch is kept, so saving between passes loses no sample.

use alloc::vec::Vec;
use core::sync::atomic::Ordering;

use glam::Vec3;

use crate::bytes::{invalid_field, open_guide_bytes, ByteReader, ByteWriter};
use crate::error::Error;

use super::guide::{check_mixture, GaussianMixture};
use super::settings::{batch_stride, GaussianMixtureSettings};
use super::vmf::VmfLobe;
use super::vmf_mixture::VmfMixture;

/// Format version written and read by this build.
pub const FORMAT_VERSION: u32 = 1;
/// Structure tag of a mixture guide.
pub const STRUCTURE_TAG: u32 = 3;

/// 32-bit words per lobe in a region's record.
const WORDS_PER_LOBE: usize = 9;

pub(crate) fn encode(guide: &GaussianMixture) -> Vec<u8> {
    let s = guide.settings();
    let (epoch, rejected_non_finite, rejected_negative, mixtures, batch) = guide.raw_state();
    let region_words = 1 + s.lobes * WORDS_PER_LOBE + batch_stride(s.lobes);
    let mut w = ByteWriter::with_capacity(128 + mixtures.len() * region_words * 4);
    w.put_header(FORMAT_VERSION, STRUCTURE_TAG);
    w.put_budget_and_resolution(s.budget_bytes, s.resolution);
    w.put_u32(s.lobes as u32);
    w.put_u32(s.split_by_normal as u32);
    w.put_f32(s.initial_q);
    w.put_f32(s.uniform_mix);
    w.put_update_rule(&s.update_rule);
    let (low, high) = guide.bounds();
    low.to_array().iter().chain(&high.to_array()).for_each(|&c| w.put_f32(c));
    guide.resolution().iter().for_each(|&n| w.put_u32(n));
    w.put_u32(epoch);
    w.put_u64(rejected_non_finite as u64);
    w.put_u64(rejected_negative as u64);
    w.put_u32(mixtures.len() as u32);
    for (mixture, row) in mixtures.iter().zip(batch.chunks_exact(batch_stride(s.lobes))) {
        let (lobes, weights, s0, s1, observations) = mixture.parts();
        w.put_u32(observations);
        for k in 0..lobes.len() {
            lobes[k].mean().to_array().iter().for_each(|&c| w.put_f32(c));
            w.put_f32(lobes[k].concentration());
            w.put_f32(weights[k]);
            w.put_f32(s0[k]);
            s1[k].to_array().iter().for_each(|&c| w.put_f32(c));
        }
        row.iter().for_each(|word| w.put_u32(word.load(Ordering::Relaxed)));
    }
    w.finish_with_checksum()
}

fn read_settings(r: &mut ByteReader<'_>) -> Result<GaussianMixtureSettings, Error> {
    let (budget_bytes, resolution) = r.budget_and_resolution()?;
    let lobes = r.u32()? as usize;
    let split_by_normal = r.flag("split_by_normal")?;
    let initial_q = r.f32()?;
    let uniform_mix = r.f32()?;
    let update_rule = r.update_rule()?;
    let settings = GaussianMixtureSettings {
        budget_bytes,
        resolution,
        lobes,
        split_by_normal,
        initial_q,
        uniform_mix,
        update_rule,
    };
    settings.validate()?;
    Ok(settings)
}

fn read_mixture(r: &mut ByteReader<'_>, lobes: usize, index: usize) -> Result<VmfMixture, Error> {
    let observations = r.u32()?;
    let mut parts = Vec::with_capacity(lobes);
    for _ in 0..lobes {
        let mean = r.vec3()?;
        let kappa = r.f32()?;
        let (weight, s0, s1) = (r.f32()?, r.f32()?, r.vec3()?);
        if !(mean.is_finite() && (mean.length() - 1.0).abs() < 1e-4) {
            return Err(invalid_field("lobe_means", index, "finite and unit length"));
        }
        let lobe = VmfLobe::with_unit_mean(mean, kappa);
        // The constructor clamps κ; a stored κ it would change was not written by this format.
        if lobe.concentration() != kappa {
            return Err(invalid_field("lobe_concentrations", index, "0 or in [1e-4, 1e4]"));
        }
        parts.push((lobe, weight, s0, s1));
    }
    let means: Vec<VmfLobe> = parts.iter().map(|p| p.0).collect();
    let weights: Vec<f32> = parts.iter().map(|p| p.1).collect();
    let s0: Vec<f32> = parts.iter().map(|p| p.2).collect();
    let s1: Vec<Vec3> = parts.iter().map(|p| p.3).collect();
    let mixture = VmfMixture::from_parts(&means, &weights, &s0, &s1, observations);
    check_mixture(&mixture, index, lobes)?;
    Ok(mixture)
}

pub(crate) fn decode(bytes: &[u8]) -> Result<GaussianMixture, Error> {
    let mut r = open_guide_bytes(bytes, FORMAT_VERSION, STRUCTURE_TAG)?;
    let settings = read_settings(&mut r)?;
    let (low, high) = (r.vec3()?, r.vec3()?);
    let resolution = [r.u32()?, r.u32()?, r.u32()?];
    let epoch = r.u32()?;
    let rejected = (r.u64()? as usize, r.u64()? as usize);
    let regions = r.u32()? as usize;
    let grid = GaussianMixture::grid_for(low, high, &settings)?;
    if grid.resolution() != resolution {
        return Err(invalid_field("grid_resolution", 0, "the resolution the settings give"));
    }
    if grid.cell_count() * settings.regions_per_cell() != regions {
        return Err(invalid_field("region_count", 0, "cells × regions per cell"));
    }
    let stride = batch_stride(settings.lobes);
    // Check the length before allocating, so a damaged count cannot demand memory.
    let needed = regions * (1 + settings.lobes * WORDS_PER_LOBE + stride) * 4;
    r.expect_remaining(needed)?;
    let guide = GaussianMixture::new(low, high, settings)?;
    let mut mixtures = Vec::with_capacity(regions);
    let mut batch = Vec::with_capacity(regions * stride);
    for index in 0..regions {
        mixtures.push(read_mixture(&mut r, settings.lobes, index)?);
        for word in 0..stride {
            let raw = r.u32()?;
            if word != 0 && !f32::from_bits(raw).is_finite() {
                return Err(invalid_field("batch", index * stride + word, "finite sums"));
            }
            batch.push(raw);
        }
    }
    r.finish()?;
    Ok(GaussianMixture::assemble(guide, epoch, rejected, mixtures, batch))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::DecodeError;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn round_trip_keeps_sampling_and_the_pending_batch() {
        let settings = GaussianMixtureSettings { resolution: Some([2, 1, 1]), ..Default::default() };
        let mut guide = GaussianMixture::new(Vec3::ZERO, Vec3::ONE, settings).unwrap();
        let region = guide.locate(Vec3::splat(0.2), Vec3::Y).unwrap();
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..500 {
            let s = guide.sample(region, rng.next_vec2());
            guide.update_sampled(region, s.direction, s.direction.y.max(0.0), s.pdf);
        }
        guide.rebuild_sampling();
        guide.update(region, Vec3::Z, 2.0);
        let bytes = guide.to_bytes();
        let mut loaded = GaussianMixture::from_bytes(&bytes).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        // A clone holds the same state, pending batch included.
        assert_eq!(guide.clone().to_bytes(), bytes);
        assert_eq!(loaded.stats(), guide.stats());
        guide.rebuild_sampling();
        loaded.rebuild_sampling();
        assert_eq!(loaded.mixture(region.index as usize), guide.mixture(region.index as usize));
        let mut wrong = bytes.clone();
        wrong[12] = 1;
        crate::reseal_checksum(&mut wrong);
        assert!(matches!(
            GaussianMixture::from_bytes(&wrong),
            Err(Error::Decode(DecodeError::WrongStructure { found: 1, expected: 3 }))
        ));
    }
}
