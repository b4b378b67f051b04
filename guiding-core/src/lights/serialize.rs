//! The byte format of a [`LightGuide`] (version 1, little-endian).
//!
//! ```text
//! "LODESTAR" magic (8 bytes) · u32 format version · u32 structure tag (5)
//! settings: u64 budget · u32 resolution given (0/1) · u32×3 resolution · f32 power_mix
//!           · f32 uniform_mix · u32 rule (0 unoccluded average, 1 mean contribution,
//!           2 visibility ratio)
//! state:    f32×3 low · f32×3 high · u32×3 grid resolution · u32 lights L
//!           · u64 rejected · L × f32 power share
//!           · cells × L × (f32 V · u32 updates · u32 shadow rays)
//! u64 FNV-1a checksum of everything before it
//! ```
//!
//! The selection CDFs are not stored: loading rebuilds them from V, as
//! [`LightGuide::rebuild_sampling`] would.

use alloc::vec::Vec;
use core::sync::atomic::Ordering;

use crate::bytes::{invalid_field, open_guide_bytes, ByteReader, ByteWriter};
use crate::error::Error;

use super::guide::LightGuide;
use super::settings::{LightGuideSettings, LightUpdateRule};

/// Format version written and read by this build.
pub const FORMAT_VERSION: u32 = 1;
/// Structure tag of a light guide.
pub const STRUCTURE_TAG: u32 = 5;

/// Bytes per (cell, light) entry in the format.
const ENTRY_BYTES: usize = 12;

fn rule_code(rule: LightUpdateRule) -> u32 {
    match rule {
        LightUpdateRule::UnoccludedAverage => 0,
        LightUpdateRule::MeanContribution => 1,
        LightUpdateRule::VisibilityRatio => 2,
    }
}

pub(crate) fn encode(guide: &LightGuide) -> Vec<u8> {
    let s = &guide.settings;
    let entries = guide.values.len();
    let mut w = ByteWriter::with_capacity(96 + guide.lights * 4 + entries * ENTRY_BYTES);
    w.put_header(FORMAT_VERSION, STRUCTURE_TAG);
    w.put_budget_and_resolution(s.budget_bytes, s.resolution);
    w.put_f32(s.power_mix);
    w.put_f32(s.uniform_mix);
    w.put_u32(rule_code(s.rule));
    let (low, high) = guide.bounds;
    low.to_array().iter().chain(&high.to_array()).for_each(|&c| w.put_f32(c));
    guide.resolution().iter().for_each(|&n| w.put_u32(n));
    w.put_u32(guide.lights as u32);
    w.put_u64(guide.rejected.load(Ordering::Relaxed) as u64);
    guide.power_share.iter().for_each(|&p| w.put_f32(p));
    for i in 0..entries {
        w.put_u32(guide.values[i].load(Ordering::Relaxed));
        w.put_u32(guide.updates[i].load(Ordering::Relaxed));
        w.put_u32(guide.shots[i].load(Ordering::Relaxed));
    }
    w.finish_with_checksum()
}

fn read_settings(r: &mut ByteReader<'_>) -> Result<LightGuideSettings, Error> {
    let (budget_bytes, resolution) = r.budget_and_resolution()?;
    let (power_mix, uniform_mix) = (r.f32()?, r.f32()?);
    let rule = match r.u32()? {
        0 => LightUpdateRule::UnoccludedAverage,
        1 => LightUpdateRule::MeanContribution,
        2 => LightUpdateRule::VisibilityRatio,
        _ => return Err(invalid_field("rule", 0, "0, 1 or 2")),
    };
    let settings = LightGuideSettings { budget_bytes, resolution, power_mix, uniform_mix, rule };
    settings.validate()?;
    Ok(settings)
}

pub(crate) fn decode(bytes: &[u8]) -> Result<LightGuide, Error> {
    let mut r = open_guide_bytes(bytes, FORMAT_VERSION, STRUCTURE_TAG)?;
    let settings = read_settings(&mut r)?;
    let (low, high) = (r.vec3()?, r.vec3()?);
    let resolution = [r.u32()?, r.u32()?, r.u32()?];
    let lights = r.u32()? as usize;
    let rejected = r.u64()?;
    if lights == 0 || lights > super::settings::MAX_LIGHTS {
        return Err(invalid_field("light_count", 0, "in 1..=2^20"));
    }
    // The shares are read before the guide is built: it needs them as powers (a
    // damaged count reserves no more than the bytes left).
    let mut power_share = Vec::with_capacity(lights.min(r.remaining() / 4));
    for index in 0..lights {
        let share = r.f32()?;
        if !(share.is_finite() && (0.0..=1.0).contains(&share)) {
            return Err(invalid_field("power_share", index, "finite and in [0, 1]"));
        }
        power_share.push(share);
    }
    let sum: f32 = power_share.iter().sum();
    if (sum - 1.0).abs() > 1e-3 {
        return Err(invalid_field("power_share", 0, "shares summing to 1"));
    }
    // The guide the settings give over these bounds, checked before its tables are
    // read, so a damaged count cannot demand memory.
    let mut guide = LightGuide::new(low, high, &power_share, settings)?;
    if guide.resolution() != resolution {
        return Err(invalid_field("grid_resolution", 0, "the resolution the settings give"));
    }
    let entries = guide.values.len();
    let needed = entries * ENTRY_BYTES;
    r.expect_remaining(needed)?;
    for i in 0..entries {
        let (value, updates, shots) = (r.u32()?, r.u32()?, r.u32()?);
        let v = f32::from_bits(value);
        if !(v.is_finite() && v >= 0.0) {
            return Err(invalid_field("values", i, "finite and non-negative"));
        }
        guide.values[i].store(value, Ordering::Relaxed);
        guide.updates[i].store(updates, Ordering::Relaxed);
        guide.shots[i].store(shots, Ordering::Relaxed);
    }
    r.finish()?;
    guide.power_share = power_share;
    guide.rejected.store(usize::try_from(rejected).unwrap_or(usize::MAX), Ordering::Relaxed);
    guide.rebuild_sampling();
    Ok(guide)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use crate::error::DecodeError;

    use super::*;
    use crate::low_discrepancy::Pcg32;

    fn learned(rule: LightUpdateRule) -> LightGuide {
        let settings = LightGuideSettings { resolution: Some([3, 2, 1]), rule, ..Default::default() };
        let mut guide = LightGuide::new(Vec3::ZERO, Vec3::new(3.0, 2.0, 1.0), &[1.0, 4.0, 0.5], settings).unwrap();
        let mut rng = Pcg32::new(7, 7);
        for _ in 0..2_000 {
            let cell = guide.locate(Vec3::new(3.0 * rng.next_f32(), 2.0 * rng.next_f32(), rng.next_f32())).unwrap();
            let light = rng.next_u32() % 3;
            guide.update(cell, light, rng.next_f32() * (light + 1) as f32, rng.next_f32() < 0.7);
        }
        guide.update(guide.locate(Vec3::ONE).unwrap(), 0, f32::NAN, true);
        guide.rebuild_sampling();
        guide
    }

    #[test]
    fn round_trip_keeps_every_probability_for_every_rule() {
        for rule in
            [LightUpdateRule::UnoccludedAverage, LightUpdateRule::MeanContribution, LightUpdateRule::VisibilityRatio]
        {
            let guide = learned(rule);
            let bytes = guide.to_bytes();
            let loaded = LightGuide::from_bytes(&bytes).unwrap();
            assert_eq!(loaded.to_bytes(), bytes, "{rule:?}");
            assert_eq!(loaded.rejected_updates(), 1);
            for cell in 0..guide.cell_count() as u32 {
                for light in 0..3 {
                    let cell = crate::LightCell(cell);
                    assert_eq!(loaded.probability(cell, light), guide.probability(cell, light), "{rule:?}");
                }
            }
        }
    }

    #[test]
    fn damaged_bytes_are_refused_with_what_is_wrong() {
        let bytes = learned(LightUpdateRule::MeanContribution).to_bytes();
        // Every truncation is an error, never a panic.
        for length in 0..bytes.len() {
            assert!(LightGuide::from_bytes(&bytes[..length]).is_err(), "length {length}");
        }
        // A flipped byte fails the checksum.
        let mut flipped = bytes.clone();
        flipped[40] ^= 1;
        assert!(matches!(LightGuide::from_bytes(&flipped), Err(Error::Decode(DecodeError::ChecksumMismatch { .. }))));
        // A negative V behind a valid checksum is named.
        let mut negative = bytes.clone();
        let first_value = bytes.len() - 8 - guide_entries(&bytes) * ENTRY_BYTES;
        negative[first_value..first_value + 4].copy_from_slice(&(-1.0f32).to_bits().to_le_bytes());
        crate::reseal_checksum(&mut negative);
        assert!(matches!(
            LightGuide::from_bytes(&negative),
            Err(Error::Decode(DecodeError::InvalidField { field: "values", index: 0, .. }))
        ));
        // Another structure's bytes are refused by their tag.
        let mut other = bytes.clone();
        other[12] = 1;
        crate::reseal_checksum(&mut other);
        assert!(matches!(
            LightGuide::from_bytes(&other),
            Err(Error::Decode(DecodeError::WrongStructure { found: 1, expected: STRUCTURE_TAG }))
        ));
    }

    fn guide_entries(bytes: &[u8]) -> usize {
        LightGuide::from_bytes(bytes).unwrap().values.len()
    }
}
