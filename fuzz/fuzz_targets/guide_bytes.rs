//! Serialized guides, raw or damaged: decoding either fails with an error or yields a
//! guide that validates, round-trips canonically and samples with finite, positive
//! pdfs. Mode bits 3–5 pick the structure (hemisphere grid, irradiance volume, mixture,
//! spatial × directional tree, and the light guide, whose decoded selections must be
//! probabilities);
//! bit 0 picks raw bytes or a real guide's bytes with edits; bit 1 truncates; bit 2
//! reseals the checksum so the edits reach the field checks behind it.
#![no_main]

use glam::{Vec2, Vec3};
use guiding_core::{
    reseal_checksum, GaussianMixture, GaussianMixtureSettings, Guide, HemisphereGrid, HemisphereGridSettings,
    HemisphereMapping, IrradianceVolume, IrradianceVolumeSettings, LightCell, LightGuide, LightGuideSettings,
    MixtureRegion, PatchLayout, ProbeId, SpatialDirectionalTree, SpatialDirectionalTreeSettings, TreeRegion, Triangle,
    VolumeRegion,
};
use libfuzzer_sys::fuzz_target;

/// A small guide of the structure `G`, shaped by `parameters`.
trait FuzzedGuide: Guide {
    fn small(parameters: &dyn Fn(usize) -> u32) -> Self;
    /// Every region, for sampling checks.
    fn regions(&self) -> Vec<Self::Region>;
}

impl FuzzedGuide for HemisphereGrid {
    fn small(p: &dyn Fn(usize) -> u32) -> Self {
        let mapping = if p(3) % 2 == 0 { HemisphereMapping::Cylindrical } else { HemisphereMapping::ConcentricSquare };
        let settings = HemisphereGridSettings {
            probe_count: Some(1 + p(0) as usize % 8),
            layout: PatchLayout { mapping, resolution: [1 + p(1) % 8, 1 + p(2) % 8] },
            ..Default::default()
        };
        let floor =
            [Triangle::new(Vec3::ZERO, Vec3::Z, Vec3::X), Triangle::new(Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0))];
        HemisphereGrid::build(&floor, settings).expect("a valid small grid")
    }

    fn regions(&self) -> Vec<ProbeId> {
        (0..self.probe_count() as u32).map(ProbeId).collect()
    }
}

impl FuzzedGuide for IrradianceVolume {
    fn small(p: &dyn Fn(usize) -> u32) -> Self {
        let settings = IrradianceVolumeSettings {
            budget_bytes: 64 << 10,
            resolution: Some([1 + p(0) % 2, 1, 1 + p(1) % 2]),
            layout: guiding_core::volume::SphereLayout { resolution: [1 + p(2) % 4, 1 + p(3) % 8] },
            split_updates_per_patch: 0.01,
            ..Default::default()
        };
        IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a valid small volume")
    }

    fn regions(&self) -> Vec<VolumeRegion> {
        let normal = Vec3::new(0.2, 0.9, -0.3).normalize();
        (0..self.leaf_count() as u32).map(|leaf| VolumeRegion { leaf, normal }).collect()
    }
}

impl FuzzedGuide for GaussianMixture {
    fn small(p: &dyn Fn(usize) -> u32) -> Self {
        let settings = GaussianMixtureSettings {
            resolution: Some([1 + p(0) % 2, 1, 1]),
            lobes: 1 + p(1) as usize % 8,
            split_by_normal: p(2) % 2 == 0,
            ..Default::default()
        };
        GaussianMixture::new(Vec3::ZERO, Vec3::ONE, settings).expect("a valid small mixture")
    }

    fn regions(&self) -> Vec<MixtureRegion> {
        // Each region folded about a normal off every axis, so both halves count.
        let normal = Vec3::new(0.3, 0.8, -0.52).normalize();
        (0..self.region_count() as u32).map(|index| MixtureRegion { index, normal }).collect()
    }
}

impl FuzzedGuide for SpatialDirectionalTree {
    fn small(p: &dyn Fn(usize) -> u32) -> Self {
        let settings = SpatialDirectionalTreeSettings {
            min_split_records: 1 + p(0) % 4,
            max_directional_depth: 1 + p(1) % 20,
            uniform_mix: if p(2) % 2 == 0 { 0.0 } else { 0.05 },
            fold_to_hemisphere: p(3) % 2 == 0,
            cosine_product: p(4) % 2 == 0,
            mixed_normal_share: if p(5) % 2 == 0 { 0.0 } else { 0.97 },
            trees_per_axis: p(6) % 2 == 0,
            second_moment: p(7) % 2 == 0,
            ..Default::default()
        };
        SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, settings).expect("a valid small tree")
    }

    fn regions(&self) -> Vec<TreeRegion> {
        let normal = Vec3::new(0.2, 0.9, -0.3).normalize();
        (0..self.leaf_count() as u32).map(|leaf| TreeRegion { leaf, normal, upper_half: false }).collect()
    }
}

fn edited_bytes<G: FuzzedGuide>(parameters: &[u8], edits: &[u8], mode: u8) -> Vec<u8> {
    let p = |i: usize| parameters.get(i).copied().unwrap_or(0) as u32;
    let mut guide = G::small(&p);
    if let Some(region) = guide.locate(Vec3::new(0.3, 0.0, 0.4), Vec3::Y) {
        for k in 0..4 {
            guide.update(region, Vec3::new(0.1 * k as f32, 0.9, 0.2).normalize(), 5.0);
        }
    }
    guide.rebuild_sampling();
    let mut bytes = guide.to_bytes();
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

fn check<G: FuzzedGuide>(mode: u8, rest: &[u8]) {
    let bytes = if mode & 1 == 0 {
        rest.to_vec()
    } else {
        let (parameters, edits) = rest.split_at(rest.len().min(5));
        edited_bytes::<G>(parameters, edits, mode)
    };
    let Ok(guide) = G::from_bytes(&bytes) else { return };
    guide.validate().expect("a decoded guide validates");
    // Decoding may store regions in a canonical order (the grid's probes in lookup
    // order), so edits may reorder them; from then on the encoding is canonical.
    let encoded = guide.to_bytes();
    let again = G::from_bytes(&encoded).expect("a re-encoded guide decodes").to_bytes();
    if let Some(offset) = (0..encoded.len().max(again.len())).find(|&i| encoded.get(i) != again.get(i)) {
        panic!("a second round trip changed byte {offset}: {:?} became {:?}", encoded.get(offset), again.get(offset));
    }
    for region in guide.regions() {
        let sample = guide.sample(region, Vec2::new(0.37, 0.71));
        assert!(sample.pdf.is_finite() && sample.pdf > 0.0, "{region:?}: {sample:?}");
        assert!(sample.direction.is_normalized(), "{region:?}: {sample:?}");
        let pdf = guide.pdf(region, sample.direction);
        assert!((pdf - sample.pdf).abs() <= 1e-4 * sample.pdf, "{region:?}: pdf {pdf} vs sample {sample:?}");
        let _ = guide.update(region, sample.direction, 1.0);
    }
}

/// The light guide's bytes, raw or a small learned guide's with edits (as for
/// [`check`]); a guide that decodes re-encodes canonically and selects by probabilities.
fn check_light_guide(mode: u8, rest: &[u8]) {
    let bytes = if mode & 1 == 0 {
        rest.to_vec()
    } else {
        let (parameters, edits) = rest.split_at(rest.len().min(3));
        let p = |i: usize| parameters.get(i).copied().unwrap_or(0) as u32;
        let settings = LightGuideSettings { resolution: Some([1 + p(0) % 3, 1, 1]), ..Default::default() };
        let powers: Vec<f32> = (0..1 + p(1) % 5).map(|l| 1.0 + l as f32).collect();
        let mut guide = LightGuide::new(Vec3::ZERO, Vec3::ONE, &powers, settings).expect("a valid small light guide");
        let cell = guide.locate(Vec3::splat(0.3)).expect("inside");
        guide.update(cell, 0, 3.0, true);
        guide.rebuild_sampling();
        let mut bytes = guide.to_bytes();
        for edit in edits.chunks_exact(3) {
            let position = u16::from_le_bytes([edit[0], edit[1]]) as usize % bytes.len();
            bytes[position] = edit[2];
        }
        if mode & 2 != 0 {
            let keep = bytes.len() - (p(2) as usize * 7) % bytes.len();
            bytes.truncate(keep);
        }
        if mode & 4 != 0 {
            reseal_checksum(&mut bytes);
        }
        bytes
    };
    let Ok(guide) = LightGuide::from_bytes(&bytes) else { return };
    let encoded = guide.to_bytes();
    assert_eq!(LightGuide::from_bytes(&encoded).expect("a re-encoded guide decodes").to_bytes(), encoded);
    for cell in (0..guide.cell_count() as u32).map(LightCell) {
        let choice = guide.select(cell, 0.61);
        assert!(choice.probability > 0.0 && choice.probability <= 1.0, "{cell:?}: {choice:?}");
        assert_eq!(choice.probability, guide.probability(cell, choice.light));
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    match (mode >> 3) % 5 {
        0 => check::<HemisphereGrid>(mode, rest),
        1 => check::<IrradianceVolume>(mode, rest),
        2 => check::<GaussianMixture>(mode, rest),
        3 => check::<SpatialDirectionalTree>(mode, rest),
        _ => check_light_guide(mode, rest),
    }
});
