//! Arbitrary streams of updates (any f32 direction and target, NaN and ∞ included),
//! rebuilds, samples, pdfs and integral estimates under every update rule: Q stays
//! finite and above the floor, pdfs stay finite and positive where sampled, estimates
//! finite, and the grid validates at the end.
#![no_main]

use glam::{Vec2, Vec3};
use guiding_core::{
    Guide, HemisphereGrid, HemisphereGridSettings, IntegralEstimator, Lambertian, LearningRate, PatchLayout, ProbeId,
    Triangle, UpdateRule,
};
use libfuzzer_sys::fuzz_target;

fn f32_at(bytes: &[u8], offset: usize) -> f32 {
    f32::from_le_bytes(bytes[offset..offset + 4].try_into().unwrap())
}

fuzz_target!(|data: &[u8]| {
    let Some((&config, operations)) = data.split_first() else { return };
    let learning_rate = match config % 5 {
        0 => LearningRate::SimpleAverage,
        1 => LearningRate::RegionVisits,
        2 => LearningRate::Exponential { alpha: 0.0 },
        3 => LearningRate::Exponential { alpha: 1.0 },
        _ => LearningRate::Global { exponent: 0.75 },
    };
    let integral = match (config / 5) % 5 {
        0 => IntegralEstimator::BsdfWeightedSum,
        1 => IntegralEstimator::StratifiedPatches,
        2 => IntegralEstimator::MaxEntry,
        3 => IntegralEstimator::PathContinuation,
        _ => IntegralEstimator::BsdfSampled,
    };
    let settings = HemisphereGridSettings {
        probe_count: Some(4),
        layout: PatchLayout { resolution: [4, 8], ..Default::default() },
        uniform_mix: if config & 0x40 != 0 { 0.0 } else { 0.02 },
        sampling_exponent: if config & 0x80 != 0 { 0.5 } else { 1.0 },
        update_rule: UpdateRule { learning_rate, integral },
        ..Default::default()
    };
    let floor = settings.q_floor;
    let quad = [Triangle::new(Vec3::ZERO, Vec3::Z, Vec3::X), Triangle::new(Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0))];
    let mut grid = HemisphereGrid::build(&quad, settings).expect("a valid grid");
    let probes = grid.probe_count() as u32;
    for operation in operations.chunks_exact(17) {
        let probe = ProbeId((operation[0] >> 2) as u32 % probes);
        let direction = Vec3::new(f32_at(operation, 1), f32_at(operation, 5), f32_at(operation, 9));
        let value = f32_at(operation, 13);
        match operation[0] % 4 {
            0 | 1 => {
                grid.update(probe, direction, value);
            }
            2 => grid.rebuild_sampling(),
            _ => {
                let u = Vec2::new(direction.x, direction.y).abs().fract().clamp(Vec2::ZERO, Vec2::splat(0.999_999));
                let sample = grid.sample(probe, u);
                assert!(sample.pdf.is_finite() && sample.pdf > 0.0, "{sample:?}");
                if let Some(unit) = direction.try_normalize() {
                    let pdf = grid.pdf(probe, unit);
                    assert!(pdf.is_finite() && pdf >= 0.0, "{pdf}");
                }
                let bsdf = Lambertian { normal: Vec3::Y, albedo: 0.8 };
                let estimate = grid.estimate_integral(probe, Vec3::Y, &bsdf, u);
                assert!(estimate.is_finite() && estimate >= 0.0, "{estimate}");
            }
        }
    }
    for probe in 0..probes {
        for patch in 0..grid.patch_count() {
            let q = grid.q(ProbeId(probe), patch);
            assert!(q.is_finite() && q >= floor, "Q[{probe}][{patch}] = {q}");
        }
    }
    grid.rebuild_sampling();
    grid.validate().expect("the grid validates after any update stream");
});
