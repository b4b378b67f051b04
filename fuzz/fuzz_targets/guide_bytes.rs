//! Serialized guides, raw or damaged: decoding either fails with an error or yields a
//! grid that validates, round-trips canonically and samples with finite, positive
//! pdfs. Mode bit 0 picks raw bytes or a real grid's bytes with edits; bit 1 truncates;
//! bit 2 reseals the checksum so the edits reach the field checks behind it.
#![no_main]

use glam::{Vec2, Vec3};
use guiding_core::{
    reseal_checksum, Guide, HemisphereGrid, HemisphereGridSettings, HemisphereMapping, PatchLayout, ProbeId, Triangle,
};
use libfuzzer_sys::fuzz_target;

fn edited_grid_bytes(parameters: &[u8], edits: &[u8], mode: u8) -> Vec<u8> {
    let p = |i: usize| parameters.get(i).copied().unwrap_or(0) as u32;
    let mapping = if p(3) % 2 == 0 { HemisphereMapping::Cylindrical } else { HemisphereMapping::ConcentricSquare };
    let settings = HemisphereGridSettings {
        probe_count: Some(1 + p(0) as usize % 8),
        layout: PatchLayout { mapping, resolution: [1 + p(1) % 8, 1 + p(2) % 8] },
        ..Default::default()
    };
    let floor =
        [Triangle::new(Vec3::ZERO, Vec3::Z, Vec3::X), Triangle::new(Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0))];
    let mut grid = HemisphereGrid::build(&floor, settings).expect("a valid small grid");
    grid.update(ProbeId(0), Vec3::new(0.1, 0.9, 0.2).normalize(), 5.0);
    grid.rebuild_sampling();
    let mut bytes = grid.to_bytes();
    for edit in edits.chunks_exact(3) {
        let position = u16::from_le_bytes([edit[0], edit[1]]) as usize % bytes.len();
        bytes[position] = edit[2];
    }
    if mode & 2 != 0 {
        let keep = bytes.len() - (p(4) as usize * 7) % bytes.len();
        bytes.truncate(keep);
    }
    if mode & 4 != 0 {
        reseal_checksum(&mut bytes);
    }
    bytes
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    let bytes = if mode & 1 == 0 {
        rest.to_vec()
    } else {
        let (parameters, edits) = rest.split_at(rest.len().min(5));
        edited_grid_bytes(parameters, edits, mode)
    };
    let Ok(grid) = HemisphereGrid::from_bytes(&bytes) else { return };
    grid.validate().expect("a decoded grid validates");
    // Decoding stores probes in lookup order, so edited positions may reorder them (with
    // all their rows); from then on the encoding is canonical.
    let encoded = grid.to_bytes();
    let again = HemisphereGrid::from_bytes(&encoded).expect("a re-encoded grid decodes").to_bytes();
    if let Some(offset) = (0..encoded.len().max(again.len())).find(|&i| encoded.get(i) != again.get(i)) {
        panic!("a second round trip changed byte {offset}: {:?} became {:?}", encoded.get(offset), again.get(offset));
    }
    for probe in 0..grid.probe_count() as u32 {
        let sample = grid.sample(ProbeId(probe), Vec2::new(0.37, 0.71));
        assert!(sample.pdf.is_finite() && sample.pdf > 0.0, "probe {probe}: {sample:?}");
        assert!(sample.direction.is_normalized());
        let pdf = grid.pdf(ProbeId(probe), sample.direction);
        assert!(pdf == sample.pdf, "probe {probe}: pdf {pdf} vs sample {sample:?}");
    }
});
