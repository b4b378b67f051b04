//! The byte format of a [`HemisphereGrid`] (version 1, little-endian).
//!
//! ```text
//! "LODESTAR" magic (8 bytes) · u32 format version · u32 structure tag (1)
//! settings: u32 mapping · u32 nu · u32 nv · u32 flags (bit 0 two_sided, bit 1
//!           cosine_product) · f32 max_normal_angle_deg
//!           · u32 max_search_rings · f32 initial_q · f32 q_floor · f32 uniform_mix
//!           · f32 sampling_exponent
//!           · u32 learning-rate kind · f32 its parameter · u32 integral estimator
//!           · u32 budget low · u32 budget high · u32 probe_count (0 = from budget)
//! state:    f32 probe_spacing · u32 epoch · u32×2 rejected non-finite · u32×2 rejected
//!           negative · u32 probe count P
//!           · P×3 f32 positions · P×3 f32 normals · P u32 probe visits
//!           · P·N f32 Q · P·N u32 patch visits · P·N f32 CDF
//! u64 FNV-1a checksum of everything before it
//! ```
//!
//! The lookup and the patch tables are derived, so they are rebuilt on load. The CDF
//! snapshot is stored, so a loaded grid samples exactly as the saved one did.

use alloc::vec::Vec;
use core::sync::atomic::Ordering;
use glam::Vec3;

use crate::bytes::{invalid_field, open_guide_bytes, ByteReader, ByteWriter};
use crate::error::{DecodeError, Error};

use super::grid::{GridState, HemisphereGrid};
use super::mapping::{HemisphereMapping, PatchLayout};
use super::settings::{HemisphereGridSettings, MAX_PROBES};

/// Format version written and read by this build.
pub const FORMAT_VERSION: u32 = 1;
/// Structure tag of a hemisphere grid.
pub const STRUCTURE_TAG: u32 = 1;

pub(crate) fn encode(grid: &HemisphereGrid) -> Vec<u8> {
    let s = grid.settings();
    let state = grid.state_for_serialization();
    let entries = state.q.len();
    let probes = state.positions.len();
    let mut w = ByteWriter::with_capacity(128 + probes * 28 + entries * 12);
    w.put_header(FORMAT_VERSION, STRUCTURE_TAG);
    w.put_u32(match s.layout.mapping {
        HemisphereMapping::Cylindrical => 0,
        HemisphereMapping::ConcentricSquare => 1,
    });
    w.put_u32(s.layout.resolution[0]);
    w.put_u32(s.layout.resolution[1]);
    w.put_u32(s.two_sided as u32 | (s.cosine_product as u32) << 1);
    w.put_f32(s.max_normal_angle_deg);
    w.put_u32(s.max_search_rings);
    w.put_f32(s.initial_q);
    w.put_f32(s.q_floor);
    w.put_f32(s.uniform_mix);
    w.put_f32(s.sampling_exponent);
    w.put_update_rule(&s.update_rule);
    w.put_u64(s.budget_bytes as u64);
    w.put_u32(s.probe_count.unwrap_or(0) as u32);
    w.put_f32(state.probe_spacing);
    w.put_u32(state.epoch);
    w.put_u64(state.rejected_non_finite as u64);
    w.put_u64(state.rejected_negative as u64);
    w.put_u32(probes as u32);
    for v in state.positions.iter().chain(state.normals) {
        v.to_array().iter().for_each(|&c| w.put_f32(c));
    }
    state.probe_visits.iter().for_each(|v| w.put_u32(v.load(Ordering::Relaxed)));
    state.q.iter().for_each(|q| w.put_u32(q.load(Ordering::Relaxed)));
    state.patch_visits.iter().for_each(|v| w.put_u32(v.load(Ordering::Relaxed)));
    state.cdf.iter().for_each(|&c| w.put_f32(c));
    w.finish_with_checksum()
}

fn read_settings(r: &mut ByteReader<'_>) -> Result<HemisphereGridSettings, Error> {
    let mapping = match r.u32()? {
        0 => HemisphereMapping::Cylindrical,
        1 => HemisphereMapping::ConcentricSquare,
        _ => return Err(invalid_field("mapping", 0, "0 (cylindrical) or 1 (concentric square)")),
    };
    let resolution = [r.u32()?, r.u32()?];
    // Files written before the cosine product hold 0 or 1 here: they read alike.
    let flags = r.u32()?;
    if flags > 3 {
        return Err(invalid_field("flags", 0, "bits 0 (two_sided) and 1 (cosine_product) only"));
    }
    let (two_sided, cosine_product) = (flags & 1 != 0, flags & 2 != 0);
    let max_normal_angle_deg = r.f32()?;
    let max_search_rings = r.u32()?;
    let initial_q = r.f32()?;
    let q_floor = r.f32()?;
    let uniform_mix = r.f32()?;
    let sampling_exponent = r.f32()?;
    let update_rule = r.update_rule()?;
    let budget_bytes = usize::try_from(r.u64()?).map_err(|_| invalid_field("budget_bytes", 0, "addressable"))?;
    let probe_count = match r.u32()? {
        0 => None,
        n => Some(n as usize),
    };
    let settings = HemisphereGridSettings {
        budget_bytes,
        probe_count,
        layout: PatchLayout { mapping, resolution },
        two_sided,
        max_normal_angle_deg,
        max_search_rings,
        initial_q,
        q_floor,
        uniform_mix,
        sampling_exponent,
        cosine_product,
        update_rule,
    };
    settings.validate()?;
    Ok(settings)
}

fn read_vec3s(r: &mut ByteReader<'_>, count: usize) -> Result<Vec<Vec3>, DecodeError> {
    (0..count).map(|_| r.vec3()).collect()
}

fn read_f32s(r: &mut ByteReader<'_>, count: usize) -> Result<Vec<f32>, DecodeError> {
    (0..count).map(|_| r.f32()).collect()
}

fn read_u32s(r: &mut ByteReader<'_>, count: usize) -> Result<Vec<u32>, DecodeError> {
    (0..count).map(|_| r.u32()).collect()
}

pub(crate) fn decode(bytes: &[u8]) -> Result<HemisphereGrid, Error> {
    let mut r = open_guide_bytes(bytes, FORMAT_VERSION, STRUCTURE_TAG)?;
    let settings = read_settings(&mut r)?;
    let probe_spacing = r.f32()?;
    if !(probe_spacing.is_finite() && probe_spacing >= 0.0) {
        return Err(invalid_field("probe_spacing", 0, "finite and non-negative"));
    }
    let epoch = r.u32()?;
    let rejected_non_finite = r.u64()? as usize;
    let rejected_negative = r.u64()? as usize;
    let probes = r.u32()? as usize;
    if probes == 0 || probes > MAX_PROBES {
        return Err(invalid_field("probe_count", 0, "in 1..=2^24"));
    }
    let patches = settings.layout.patch_count();
    let entries = probes.checked_mul(patches).ok_or_else(|| invalid_field("probe_count", 0, "addressable"))?;
    // Check the length before allocating, so a damaged count cannot demand memory.
    let needed = entries
        .checked_mul(12)
        .and_then(|bytes| bytes.checked_add(probes * 28))
        .ok_or_else(|| invalid_field("probe_count", 0, "addressable"))?;
    r.expect_remaining(needed)?;
    let positions = read_vec3s(&mut r, probes)?;
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(invalid_field("positions", i, "finite"));
    }
    let normals = read_vec3s(&mut r, probes)?;
    if let Some(i) = normals.iter().position(|n| !(n.is_finite() && (n.length() - 1.0).abs() <= 1e-5)) {
        return Err(invalid_field("normals", i, "finite and unit length"));
    }
    let probe_visits = read_u32s(&mut r, probes)?;
    let q = read_f32s(&mut r, entries)?;
    if let Some(i) = q.iter().position(|&q| !(q.is_finite() && q >= settings.q_floor)) {
        return Err(invalid_field("q", i, "finite and at least q_floor"));
    }
    let patch_visits = read_u32s(&mut r, entries)?;
    let cdf = read_f32s(&mut r, entries)?;
    r.finish()?;
    let grid = HemisphereGrid::assemble(
        settings,
        GridState {
            probe_spacing,
            positions,
            normals,
            probe_visits,
            q,
            patch_visits,
            cdf: Some(cdf),
            epoch,
            rejected_non_finite,
            rejected_negative,
        },
    );
    crate::Guide::validate(&grid)?;
    Ok(grid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Triangle;
    use crate::guide::Guide;
    use crate::hemisphere::HemisphereGridSettings;

    fn small_grid() -> HemisphereGrid {
        let quad = [
            Triangle::new(Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)),
            Triangle::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y),
        ];
        let settings = HemisphereGridSettings { probe_count: Some(6), ..Default::default() };
        HemisphereGrid::build(&quad, settings).unwrap()
    }

    fn decode_error(bytes: &[u8]) -> Error {
        match decode(bytes) {
            Ok(_) => panic!("the buffer must be rejected"),
            Err(e) => e,
        }
    }

    #[test]
    fn header_errors_name_what_is_wrong() {
        let bytes = small_grid().to_bytes();
        assert_eq!(decode_error(b"not a guide"), Error::Decode(DecodeError::BadMagic));
        assert_eq!(decode_error(&[]), Error::Decode(DecodeError::BadMagic));
        let mut version = bytes.clone();
        version[8] = 9;
        crate::bytes::reseal_checksum(&mut version);
        assert_eq!(decode_error(&version), Error::Decode(DecodeError::UnsupportedVersion { found: 9, supported: 1 }));
        let mut structure = bytes.clone();
        structure[12] = 7;
        crate::bytes::reseal_checksum(&mut structure);
        assert_eq!(decode_error(&structure), Error::Decode(DecodeError::WrongStructure { found: 7, expected: 1 }));
        let mut flipped = bytes.clone();
        flipped[40] ^= 4;
        assert!(matches!(decode_error(&flipped), Error::Decode(DecodeError::ChecksumMismatch { .. })));
    }

    #[test]
    fn truncation_and_trailing_bytes_are_caught_behind_a_valid_checksum() {
        let bytes = small_grid().to_bytes();
        let mut short = bytes[..bytes.len() - 20].to_vec();
        short.extend_from_slice(&[0; 8]);
        crate::bytes::reseal_checksum(&mut short);
        assert!(matches!(decode_error(&short), Error::Decode(DecodeError::Truncated { .. })));
        let mut long = bytes[..bytes.len() - 8].to_vec();
        long.extend_from_slice(&[0; 4 + 8]);
        crate::bytes::reseal_checksum(&mut long);
        assert!(matches!(decode_error(&long), Error::Decode(DecodeError::TrailingBytes { count: 4 })));
        for cut in 0..bytes.len() {
            assert!(decode(&bytes[..cut]).is_err());
        }
    }

    #[test]
    fn out_of_range_fields_are_named() {
        let grid = small_grid();
        let bytes = grid.to_bytes();
        let probes = grid.probe_count();
        let entries = probes * grid.patch_count();
        // Header 16 bytes, settings 64, state scalars 28: the positions start at byte 108.
        let positions = 108;
        let q = positions + probes * 28;
        let cdf = q + entries * 8;
        let cases: [(usize, [u8; 4], &str); 4] = [
            (positions, f32::NAN.to_le_bytes(), "positions"),
            (positions + probes * 12, 5f32.to_le_bytes(), "normals"),
            (q + 4 * 5, (-1.0f32).to_le_bytes(), "q"),
            (cdf + 4, 2.0f32.to_le_bytes(), "cdf"),
        ];
        for (offset, value, field) in cases {
            let mut damaged = bytes.clone();
            damaged[offset..offset + 4].copy_from_slice(&value);
            crate::bytes::reseal_checksum(&mut damaged);
            match decode_error(&damaged) {
                Error::Decode(DecodeError::InvalidField { field: named, .. }) => assert_eq!(named, field),
                other => panic!("{field}: {other:?}"),
            }
        }
        let mut mapping = bytes.clone();
        mapping[16] = 5;
        crate::bytes::reseal_checksum(&mut mapping);
        assert!(matches!(decode_error(&mapping), Error::Decode(DecodeError::InvalidField { field: "mapping", .. })));
        let mut alpha = bytes;
        alpha[56..60].copy_from_slice(&0u32.to_le_bytes());
        alpha[60..64].copy_from_slice(&7.0f32.to_le_bytes());
        crate::bytes::reseal_checksum(&mut alpha);
        assert!(matches!(decode_error(&alpha), Error::InvalidSetting { name: "learning_rate.alpha", .. }));
    }
}
