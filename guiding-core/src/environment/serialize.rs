//! The byte format of an [`EnvTileGuide`] (version 1, little-endian).
//!
//! ```text
//! "LODESTAR" magic (8 bytes) · u32 format version · u32 structure tag (6)
//! settings:    u64 budget · u32 resolution given (0/1) · u32×3 resolution · u32×2 tiles
//!              · f32 power_mix · f32 uniform_mix
//! environment: u32 map width · u32 map height · u32 sun (0/1) · u32 lobes L
//!              · L × f32 power share (the fingerprint the loading environment must match)
//! state:       f32×3 low · f32×3 high · u32×3 grid resolution · u64 rejected
//!              · cells × L × (f32 V · u32 updates)
//! u64 FNV-1a checksum of everything before it
//! ```
//!
//! The environment's tiles and sun belong to the scene: the reader is given them and
//! checks them against the fingerprint. The lobe CDFs are rebuilt on load.

use alloc::vec::Vec;
use core::sync::atomic::Ordering;

use crate::bytes::{invalid_field, open_guide_bytes, ByteReader, ByteWriter};
use crate::error::Error;

use super::guide::EnvTileGuide;
use super::settings::EnvTileGuideSettings;
use super::sun::SunDisk;
use super::tiles::EnvironmentTiles;

/// Format version written and read by this build.
pub const FORMAT_VERSION: u32 = 1;
/// Structure tag of an environment-tile guide.
pub const STRUCTURE_TAG: u32 = 6;

/// Bytes per (cell, lobe) entry in the format.
const ENTRY_BYTES: usize = 8;

pub(crate) fn encode(guide: &EnvTileGuide) -> Vec<u8> {
    let s = &guide.settings;
    let entries = guide.values.len();
    let lobes = guide.power_share.len();
    let mut w = ByteWriter::with_capacity(128 + lobes * 4 + entries * ENTRY_BYTES);
    w.put_header(FORMAT_VERSION, STRUCTURE_TAG);
    w.put_budget_and_resolution(s.budget_bytes, s.resolution);
    s.tiles.iter().for_each(|&n| w.put_u32(n));
    w.put_f32(s.power_mix);
    w.put_f32(s.uniform_mix);
    let (width, height) = guide.tiles.size();
    w.put_u32(width as u32);
    w.put_u32(height as u32);
    w.put_u32(guide.sun.is_some() as u32);
    w.put_u32(lobes as u32);
    guide.power_share.iter().for_each(|&p| w.put_f32(p));
    let (low, high) = guide.bounds;
    low.to_array().iter().chain(&high.to_array()).for_each(|&c| w.put_f32(c));
    guide.resolution().iter().for_each(|&n| w.put_u32(n));
    w.put_u64(guide.rejected.load(Ordering::Relaxed) as u64);
    for i in 0..entries {
        w.put_u32(guide.values[i].load(Ordering::Relaxed));
        w.put_u32(guide.updates[i].load(Ordering::Relaxed));
    }
    w.finish_with_checksum()
}

fn read_settings(r: &mut ByteReader<'_>) -> Result<EnvTileGuideSettings, Error> {
    let (budget_bytes, resolution) = r.budget_and_resolution()?;
    let tiles = [r.u32()?, r.u32()?];
    let (power_mix, uniform_mix) = (r.f32()?, r.f32()?);
    let settings = EnvTileGuideSettings { budget_bytes, resolution, tiles, power_mix, uniform_mix };
    settings.validate()?;
    Ok(settings)
}

pub(crate) fn decode(bytes: &[u8], tiles: EnvironmentTiles, sun: Option<SunDisk>) -> Result<EnvTileGuide, Error> {
    let mut r = open_guide_bytes(bytes, FORMAT_VERSION, STRUCTURE_TAG)?;
    let settings = read_settings(&mut r)?;
    let (width, height) = (r.u32()? as usize, r.u32()? as usize);
    let has_sun = r.flag("sun")?;
    let lobes = r.u32()? as usize;
    let incompatible = Err(Error::Incompatible { what: "environment" });
    // The environment's own lobe count bounds what is read next.
    if (width, height) != tiles.size() || has_sun != sun.is_some() || lobes != tiles.tile_count() + usize::from(has_sun)
    {
        return incompatible;
    }
    let mut shares = Vec::with_capacity(lobes);
    for _ in 0..lobes {
        shares.push(r.f32()?);
    }
    let (low, high) = (r.vec3()?, r.vec3()?);
    let resolution = [r.u32()?, r.u32()?, r.u32()?];
    let rejected = r.u64()?;
    // The guide these settings give over the environment it is loaded for; its lobes'
    // shares must be the stored ones, bit for bit.
    let mut guide = EnvTileGuide::new(low, high, tiles, sun, settings)?;
    if guide.power_share.iter().zip(&shares).any(|(a, b)| a.to_bits() != b.to_bits()) {
        return incompatible;
    }
    if guide.resolution() != resolution {
        return Err(invalid_field("grid_resolution", 0, "the resolution the settings give"));
    }
    let entries = guide.values.len();
    let needed = entries * ENTRY_BYTES;
    r.expect_remaining(needed)?;
    for i in 0..entries {
        let (value, updates) = (r.u32()?, r.u32()?);
        let v = f32::from_bits(value);
        if !(v.is_finite() && v >= 0.0) {
            return Err(invalid_field("values", i, "finite and non-negative"));
        }
        guide.values[i].store(value, Ordering::Relaxed);
        guide.updates[i].store(updates, Ordering::Relaxed);
    }
    r.finish()?;
    guide.rejected.store(usize::try_from(rejected).unwrap_or(usize::MAX), Ordering::Relaxed);
    guide.rebuild_sampling();
    Ok(guide)
}

#[cfg(test)]
mod tests {
    use crate::error::DecodeError;
    use glam::{Vec2, Vec3};

    use super::*;
    use crate::low_discrepancy::Pcg32;
    use crate::DirectionalDistribution;

    fn environment() -> (EnvironmentTiles, Option<SunDisk>) {
        let (width, height) = (16, 8);
        let luminance: Vec<f32> = (0..width * height).map(|i| 0.1 + (i % 7) as f32).collect();
        let tiles = EnvironmentTiles::new(width, height, &luminance, [4, 2]).unwrap();
        (tiles, Some(SunDisk::new(Vec3::new(0.3, 0.8, 0.2).normalize(), 0.01, 1e4).unwrap()))
    }

    fn learned() -> EnvTileGuide {
        let (tiles, sun) = environment();
        let settings = EnvTileGuideSettings { resolution: Some([2, 1, 2]), tiles: [4, 2], ..Default::default() };
        let mut guide = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, sun, settings).unwrap();
        let mut rng = Pcg32::new(3, 3);
        for _ in 0..2_000 {
            let cell = guide.locate(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())).unwrap();
            let sample = guide.distribution(cell).sample_lobe(rng.next_f32(), rng.next_vec2());
            guide.update(cell, &sample, rng.next_f32() * sample.direction.y.max(0.0));
        }
        guide.rebuild_sampling();
        guide
    }

    #[test]
    fn round_trip_keeps_every_distribution() {
        let guide = learned();
        let bytes = guide.to_bytes();
        let (tiles, sun) = environment();
        let loaded = EnvTileGuide::from_bytes(&bytes, tiles, sun).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        for cell in 0..guide.cell_count() as u32 {
            let cell = crate::environment::EnvCell(cell);
            let d = Vec3::new(0.2, 0.7, -0.4).normalize();
            assert_eq!(loaded.distribution(cell).pdf(d), guide.distribution(cell).pdf(d));
            let u = Vec2::new(0.3, 0.9);
            assert_eq!(loaded.distribution(cell).sample(u), guide.distribution(cell).sample(u));
        }
    }

    #[test]
    fn another_environment_or_damaged_bytes_are_refused() {
        let bytes = learned().to_bytes();
        let (tiles, _) = environment();
        // Without its sun the environment is another one.
        assert!(matches!(
            EnvTileGuide::from_bytes(&bytes, tiles, None),
            Err(Error::Incompatible { what: "environment" })
        ));
        let brighter: Vec<f32> = (0..16 * 8).map(|i| 1.0 + (i % 5) as f32).collect();
        let other = EnvironmentTiles::new(16, 8, &brighter, [4, 2]).unwrap();
        assert!(matches!(
            EnvTileGuide::from_bytes(&bytes, other, environment().1),
            Err(Error::Incompatible { what: "environment" })
        ));
        for length in 0..bytes.len() {
            let (tiles, sun) = environment();
            assert!(EnvTileGuide::from_bytes(&bytes[..length], tiles, sun).is_err(), "length {length}");
        }
        let mut flipped = bytes.clone();
        flipped[30] ^= 4;
        let (tiles, sun) = environment();
        assert!(matches!(
            EnvTileGuide::from_bytes(&flipped, tiles, sun),
            Err(Error::Decode(DecodeError::ChecksumMismatch { .. }))
        ));
    }
}
