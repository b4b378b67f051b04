//! Stiff and extreme cases of guiding-core, called directly (the scene-level ones are in
//! `reference-tracer/tests/stiff_scenes.rs`; NaN/∞ arguments of the C ABI in
//! `adapters/capi/tests/c/api_errors.c`). Each case asserts finite output and, where the
//! answer is known, the answer.

use glam::{Vec2, Vec3};
use guiding_core::cdf::{build_cdf, cdf_probability, PROBABILITY_QUANTUM};
use guiding_core::validation::pdf_integral;
use guiding_core::{
    DirectionalDistribution, Error, Guide, HemisphereGrid, HemisphereGridSettings, HemisphereMapping,
    IntegralEstimator, LearningRate, PatchLayout, ProbeId, Triangle, UpdateOutcome, UpdateRule,
};

/// A 2×2 floor quad facing +y, scaled by `scale` and moved by `offset`.
fn floor(scale: f32, offset: Vec3) -> [Triangle; 2] {
    let p = |x: f32, z: f32| offset + scale * Vec3::new(x, 0.0, z);
    [Triangle::new(p(-1.0, -1.0), p(-1.0, 1.0), p(1.0, 1.0)), Triangle::new(p(-1.0, -1.0), p(1.0, 1.0), p(1.0, -1.0))]
}

fn grid_with(settings: HemisphereGridSettings) -> HemisphereGrid {
    HemisphereGrid::build(&floor(1.0, Vec3::ZERO), settings).expect("a valid grid")
}

#[test]
fn cdf_accumulation_keeps_unit_entries_beside_one_of_two_to_the_24() {
    // 4096 entries of 1 beside one of 2²⁴: a sum in f32 stays 2²⁴ (its ulp is 2), which
    // would leave the small entries no probability at all. Accumulated in f64 and rounded
    // cumulatively, they keep their mass to within one quantum (each just under one
    // quantum, so a few round to zero; the defensive uniform share of the guides keeps
    // every patch positive, see the next test).
    let mut weights = vec![1.0f32; 4097];
    weights[0] = 16_777_216.0;
    let f32_total = weights.iter().fold(0.0f32, |sum, &w| sum + w);
    assert_eq!(f32_total, 16_777_216.0, "the hazard this test guards against");
    let mut cdf = vec![0.0f32; weights.len()];
    build_cdf(&mut cdf, 0.0, |k| weights[k]);
    let probabilities: Vec<f32> = (1..weights.len()).map(|k| cdf_probability(&cdf, k)).collect();
    assert!(probabilities.iter().all(|&p| p == 0.0 || p == PROBABILITY_QUANTUM));
    let sampled = probabilities.iter().filter(|&&p| p > 0.0).count();
    assert!(sampled >= 4094, "{sampled} of 4096 small entries keep their quantum");
    let small_mass: f64 = probabilities.iter().map(|&p| p as f64).sum();
    let exact = 4096.0 / (16_777_216.0 + 4096.0);
    assert!((small_mass - exact).abs() <= PROBABILITY_QUANTUM as f64, "{small_mass} vs {exact}");
}

#[test]
fn q_spanning_1e_minus_30_to_1e30_keeps_every_patch_sampleable() {
    let mut grid = grid_with(HemisphereGridSettings { probe_count: Some(4), ..Default::default() });
    let patches = grid.patch_count();
    let values: Vec<f32> = (0..patches).map(|k| 10f32.powf(-30.0 + 60.0 * k as f32 / (patches - 1) as f32)).collect();
    grid.set_q_values(ProbeId(0), &values);
    grid.rebuild_sampling();
    let distribution = grid.distribution(ProbeId(0));
    let integral = pdf_integral(&|d| distribution.pdf(d), Vec3::Y, 64, 6);
    assert!((integral - 1.0).abs() < 1e-3, "pdf integral {integral}");
    // The defensive uniform share keeps every patch, even Q = 1e-30 beside 1e30, at a
    // positive probability; the brightest patch takes the rest.
    let floor_pdf = 0.02 / patches as f32 / grid.settings().layout.patch_solid_angle();
    let mut rng = guiding_core::Pcg32::new(3, 1);
    let top_pdf = {
        // The 1e30 patch's exact share: (1 - mix)·Q/ΣQ + mix/N.
        let total: f64 = values.iter().map(|&q| q as f64).sum();
        (0.98 * 1e30 / total + 0.02 / patches as f64) as f32 / grid.settings().layout.patch_solid_angle()
    };
    let mut brightest = 0u32;
    let trials = 10_000;
    for _ in 0..trials {
        let sample = distribution.sample(rng.next_vec2());
        assert!(sample.pdf.is_finite() && sample.pdf >= 0.99 * floor_pdf, "{sample:?}");
        brightest += ((sample.pdf - top_pdf).abs() < 1e-3 * top_pdf) as u32;
    }
    let p_top = (top_pdf * grid.settings().layout.patch_solid_angle()) as f64;
    let expected = p_top * trials as f64;
    let sigma = (expected * (1.0 - p_top)).sqrt();
    assert!(
        (brightest as f64 - expected).abs() < 5.0 * sigma,
        "{brightest} samples in the 1e30 patch, {expected} expected"
    );
}

#[test]
fn learning_rates_zero_and_one_with_extreme_targets() {
    for (alpha, target, expected) in [(0.0, 1e30, 1e-2f32), (1.0, 1e30, 1e30), (1.0, 1e-30, 1e-30), (1.0, 0.0, 0.0)] {
        let settings = HemisphereGridSettings {
            probe_count: Some(1),
            update_rule: UpdateRule {
                learning_rate: LearningRate::Exponential { alpha },
                integral: IntegralEstimator::BsdfWeightedSum,
            },
            ..Default::default()
        };
        let mut grid = grid_with(settings);
        assert_eq!(grid.update(ProbeId(0), Vec3::Y, target), UpdateOutcome::Accepted);
        let q = grid.q(ProbeId(0), grid.settings().layout.patch_of(Vec3::Z).unwrap());
        // Q never drops below the floor (f32::MIN_POSITIVE), so a target of 0 stores it.
        assert_eq!(q, expected.max(f32::MIN_POSITIVE), "alpha {alpha}, target {target}");
        grid.rebuild_sampling();
        grid.validate().unwrap();
    }
}

#[test]
fn budgets_too_small_one_probe_and_huge_resolutions() {
    let too_small = HemisphereGridSettings { budget_bytes: 512, ..Default::default() };
    let error = HemisphereGrid::build(&floor(1.0, Vec3::ZERO), too_small).unwrap_err();
    assert!(matches!(error, Error::BudgetTooSmall { budget_bytes: 512, .. }), "{error}");
    assert!(error.to_string().contains("cannot hold one region"), "{error}");

    let huge = HemisphereGridSettings {
        layout: PatchLayout { mapping: HemisphereMapping::Cylindrical, resolution: [1 << 16, 1 << 16] },
        ..Default::default()
    };
    let error = HemisphereGrid::build(&floor(1.0, Vec3::ZERO), huge).unwrap_err();
    assert!(error.to_string().contains("exceeds the limit"), "{error}");

    // One probe covers the floor: every hit within reach finds it and samples above it.
    let mut one = grid_with(HemisphereGridSettings { probe_count: Some(1), ..Default::default() });
    assert_eq!(one.probe_count(), 1);
    one.update(ProbeId(0), Vec3::new(0.3, 0.9, 0.1).normalize(), 4.0);
    one.rebuild_sampling();
    let probe = one.locate(one.probe_positions()[0] + Vec3::new(0.1, 0.0, -0.1), Vec3::Y).expect("the one probe");
    let sample = one.sample(probe, Vec2::new(0.3, 0.6));
    assert!(sample.pdf.is_finite() && sample.pdf > 0.0 && sample.direction.y >= 0.0);
}

#[test]
fn grazing_directions_and_degenerate_normals() {
    let mut grid = grid_with(HemisphereGridSettings { probe_count: Some(8), ..Default::default() });
    let probe = grid.locate(Vec3::ZERO, Vec3::Y).unwrap();
    // cos θ from 1e-6 down to 0 and just below the horizon.
    for cos_theta in [1e-6f32, 1e-7, 1e-9, 0.0, -1e-9] {
        let direction = Vec3::new((1.0 - cos_theta * cos_theta).sqrt(), cos_theta, 0.0);
        let outcome = grid.update(probe, direction, 1.0);
        if cos_theta < 0.0 {
            assert_eq!(outcome, UpdateOutcome::OutsideDomain);
        }
        let pdf = grid.pdf(probe, direction);
        assert!(pdf.is_finite() && pdf >= 0.0, "cos {cos_theta}: pdf {pdf}");
    }
    grid.rebuild_sampling();
    grid.validate().unwrap();
    // Samples at the very edge of the square stay on the hemisphere with finite pdfs.
    for u in [Vec2::new(0.0, 0.0), Vec2::new(1.0 - f32::EPSILON, 0.5), Vec2::new(0.999_999, 0.999_999)] {
        let sample = grid.sample(probe, u);
        assert!(sample.pdf.is_finite() && sample.pdf > 0.0 && sample.direction.is_normalized(), "{u}: {sample:?}");
        assert!(sample.direction.y >= 0.0);
    }
    // Zero-length, NaN and flipped normals find no probe (the caller samples its BSDF).
    assert_eq!(grid.locate(Vec3::ZERO, Vec3::ZERO), None);
    assert_eq!(grid.locate(Vec3::ZERO, Vec3::NAN), None);
    assert_eq!(grid.locate(Vec3::ZERO, -Vec3::Y), None);
    assert_eq!(grid.locate(Vec3::NAN, Vec3::Y), None);
    // A normal that is not unit length is normalised, not trusted.
    assert_eq!(grid.locate(Vec3::ZERO, Vec3::Y * 1e-20), Some(probe));
}

#[test]
fn far_from_the_origin_and_at_any_scale_the_grid_behaves_the_same() {
    // (An offset of 1e5 with a scale of 1e-4 is not among the cases: the whole scene would
    // be smaller than one f32 step at 1e5.)
    let settings = HemisphereGridSettings { probe_count: Some(64), ..Default::default() };
    let light = Vec3::new(0.4, 0.8, -0.2).normalize();
    let mut original = HemisphereGrid::build(&floor(1.0, Vec3::ZERO), settings).unwrap();
    for (scale, offset) in [(1.0, Vec3::splat(1e5)), (1e-4, Vec3::ZERO), (1e4, Vec3::ZERO), (1e4, Vec3::splat(1e5))] {
        let mut moved = HemisphereGrid::build(&floor(scale, offset), settings).unwrap();
        assert_eq!(moved.probe_count(), original.probe_count());
        // Query beside each probe of the original and at the same place in the moved
        // scene: both find corresponding probes and teach them the same light.
        let mut pairs = Vec::new();
        for (i, &p) in original.probe_positions().to_vec().iter().enumerate() {
            let query = p + Vec3::new(0.01, 0.0, -0.01) * (i % 3) as f32;
            let a = original.locate(query, Vec3::Y).expect("a probe in the original");
            let b = moved.locate(offset + scale * query, Vec3::Y).expect("a probe in the moved scene");
            let mapped = (moved.probe_positions()[b.0 as usize] - offset) / scale;
            let ulps = 4.0 * f32::EPSILON * (offset.abs().max_element() + 2.0 * scale) / scale;
            let distance = original.probe_positions()[a.0 as usize].distance(mapped);
            assert!(distance <= ulps, "scale {scale}, offset {offset}: probe {i} found {distance} away");
            original.update(a, light, 10.0);
            moved.update(b, light, 10.0);
            pairs.push((a, b));
        }
        original.rebuild_sampling();
        moved.rebuild_sampling();
        for (a, b) in pairs {
            let (pa, pb) = (original.pdf(a, light), moved.pdf(b, light));
            assert!(pa.is_finite() && pa == pb, "scale {scale}, offset {offset}: pdf {pa} vs {pb}");
            let (sa, sb) = (original.sample(a, Vec2::new(0.3, 0.7)), moved.sample(b, Vec2::new(0.3, 0.7)));
            assert!(sa.direction.distance(sb.direction) < 1e-5 && sa.pdf == sb.pdf, "{sa:?} vs {sb:?}");
        }
        original = HemisphereGrid::build(&floor(1.0, Vec3::ZERO), settings).unwrap();
    }
}
