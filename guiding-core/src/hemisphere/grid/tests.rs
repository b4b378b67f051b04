//! The hemisphere grid's own tests: learning, the cosine product, the integral estimates.

use super::*;
use crate::cdf::cdf_probability;
use crate::distribution::DirectionalDistribution;
use crate::hemisphere::ProbeSet;
use crate::update_rule::IntegralEstimator;
use alloc::vec;

/// A grid of one probe at the origin facing +z, and that probe.
pub(in crate::hemisphere) fn one_probe(settings: HemisphereGridSettings) -> (HemisphereGrid, ProbeId) {
    let probes = ProbeSet { positions: vec![Vec3::ZERO], normals: vec![Vec3::Z], spacing: 1.0 };
    let grid = HemisphereGrid::from_probes(&probes, settings).unwrap();
    let probe = grid.locate(Vec3::ZERO, Vec3::Z).unwrap();
    (grid, probe)
}

/// Learns `radiance` at one probe through directions drawn by the grid with
/// probability `p_guide`, cosine-weighted otherwise, rebuilding between rounds;
/// `weighted` passes each direction's pdf (`update_sampled`), else none (`update`).
fn learn_through_mixture(p_guide: f32, radiance: impl Fn(Vec3) -> f32, weighted: bool) -> (HemisphereGrid, ProbeId) {
    let (mut grid, probe) = one_probe(HemisphereGridSettings::default());
    let mut rng = crate::Pcg32::new(9, 2);
    for _ in 0..4 {
        let d = grid.distribution(probe);
        for _ in 0..100_000 {
            let (wi, pdf) = crate::validation::sample_guide_or_cosine(&d, p_guide, &mut rng);
            if weighted {
                grid.update_sampled(probe, wi, radiance(wi), pdf);
            } else {
                grid.update(probe, wi, radiance(wi));
            }
        }
        grid.rebuild_sampling();
    }
    (grid, probe)
}

/// Bug 2 of the guiding issue: the same radiance field learned through mixtures that
/// sample the grid with probability 0.1 and 0.9 (the rest cosine-weighted) gives the
/// same Q, each patch's mean over its solid angle. The field is bright within 0.02
/// of the horizon, inside the lowest ring of patches (0 ≤ cos θ < 1/8), where
/// cosine-weighted directions seldom go and the grid's (uniform in a patch) often do.
#[test]
fn learned_q_does_not_depend_on_the_density_that_drew_the_directions() {
    let radiance = |d: Vec3| if d.z < 0.02 { 50.0 } else { 1.0 };
    let layout = HemisphereGridSettings::default().layout;
    let horizon = layout.patch_of(Vec3::new(0.999, 0.0, 0.01).normalize()).unwrap();
    // The patch's mean: 50 over 0.02 of its 0.125 in cos θ (uniform in solid angle).
    let exact = (0.02 * 50.0 + 0.105) / 0.125;
    let q = |p_guide, weighted| {
        let (grid, probe) = learn_through_mixture(p_guide, radiance, weighted);
        grid.q(probe, horizon) as f64
    };
    crate::q_table::assert_learning_ignores_the_density(q, exact);
}

/// Q^γ with γ < 1 keeps the order of the patches but moves their probabilities
/// towards uniform.
#[test]
fn a_sampling_exponent_below_one_tempers_the_distribution() {
    let probabilities = |exponent: f32| {
        let settings = HemisphereGridSettings { uniform_mix: 0.0, sampling_exponent: exponent, ..Default::default() };
        let (mut grid, probe) = one_probe(settings);
        let values: alloc::vec::Vec<f32> = (0..grid.patch_count()).map(|k| 1.0 + (k % 4) as f32 * 10.0).collect();
        grid.set_q_values(probe, &values);
        grid.rebuild_sampling();
        let row = &grid.cdf()[..grid.patch_count()];
        (0..4).map(|k| cdf_probability(row, k)).collect::<alloc::vec::Vec<f32>>()
    };
    let (sharp, tempered) = (probabilities(1.0), probabilities(0.5));
    assert!((sharp[3] / sharp[0] - 31.0).abs() < 0.01, "{sharp:?}");
    assert!((tempered[3] / tempered[0] - libm::sqrtf(31.0)).abs() < 0.01, "{tempered:?}");
}

/// The cosine product samples a patch by Q·∫cos: under a uniform Q it is the cosine
/// distribution patch by patch, and a patch's pdf stays P(patch)/ΔΩ, so the pdf of
/// a sampled direction is the one `pdf` returns. Its flag survives serialization.
#[test]
fn the_cosine_product_weighs_each_patch_by_its_cosine_integral() {
    let settings = HemisphereGridSettings { uniform_mix: 0.0, cosine_product: true, ..Default::default() };
    let (mut grid, probe) = one_probe(settings);
    grid.set_q_values(probe, &alloc::vec![3.0; grid.patch_count()]);
    grid.rebuild_sampling();
    let row = &grid.cdf()[..grid.patch_count()];
    for (k, &cos_integral) in grid.patch_cos_integrals().iter().enumerate() {
        let expected = cos_integral / PI;
        assert!(
            (cdf_probability(row, k) - expected).abs() < 1e-5,
            "patch {k}: {} against {expected}",
            cdf_probability(row, k)
        );
    }
    let mut rng = crate::Pcg32::new(5, 5);
    for _ in 0..100 {
        let s = grid.sample(probe, rng.next_vec2());
        assert_eq!(s.pdf, grid.pdf(probe, s.direction));
    }
    let decoded = HemisphereGrid::from_bytes(&grid.to_bytes()).unwrap();
    assert!(decoded.settings().cosine_product);
    let plain = one_probe(HemisphereGridSettings::default()).0;
    assert!(!HemisphereGrid::from_bytes(&plain.to_bytes()).unwrap().settings().cosine_product);
}

/// The running Lambertian sum that makes the Lambertian estimate O(1) matches the
/// exact sum after any mix of updates and rebuilds.
#[test]
fn the_running_lambertian_sum_matches_the_exact_sum() {
    let (mut grid, probe) = one_probe(HemisphereGridSettings::default());
    let mut rng = crate::Pcg32::new(4, 4);
    for round in 0..5 {
        for _ in 0..2000 {
            let d = crate::UniformHemisphere::new(Vec3::Z).sample(rng.next_vec2()).direction;
            grid.update(probe, d, rng.next_f32() * 10.0 * (round + 1) as f32);
        }
        let running = atomic_f32::load(&grid.lambertian_sums[0]) as f64;
        let exact = weighted_sum(grid.q_row(probe), &grid.patch_cos_integrals);
        assert!((running - exact).abs() <= 1e-4 * exact, "{running} vs {exact}");
        grid.rebuild_sampling();
    }
}

/// A glossy lobe about the mirror direction that samples itself uniformly over the
/// hemisphere: its one-sample estimate averages to the stratified sum.
struct UniformlySampledLobe;

impl ScatteringFunction for UniformlySampledLobe {
    fn eval_cos(&self, wi: Vec3, wo: Vec3) -> f32 {
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        if wi.z <= 0.0 {
            return 0.0;
        }
        3.0 * libm::powf(wi.dot(mirror).max(0.0), 8.0) * wi.z
    }

    fn sample_cos(&self, wo: Vec3, u: Vec2) -> Option<crate::SampledDirection> {
        let sample = crate::UniformHemisphere::new(Vec3::Z).sample(u);
        Some(crate::SampledDirection { wi: sample.direction, weight: self.eval_cos(sample.direction, wo) / sample.pdf })
    }

    fn can_sample(&self) -> bool {
        true
    }
}

/// The BSDF-sampled estimate is unbiased for the piecewise-constant Q: its mean over
/// many draws matches the stratified-patch estimate's (itself unbiased).
#[test]
fn the_bsdf_sampled_estimate_averages_to_the_stratified_one() {
    let estimate = |integral: IntegralEstimator, rng: &mut crate::Pcg32, n: usize| {
        let settings = HemisphereGridSettings {
            update_rule: crate::UpdateRule { integral, ..Default::default() },
            ..Default::default()
        };
        let (mut grid, probe) = one_probe(settings);
        let values: alloc::vec::Vec<f32> = (0..grid.patch_count()).map(|k| 0.5 + (k % 7) as f32).collect();
        grid.set_q_values(probe, &values);
        grid.rebuild_sampling();
        let wo = Vec3::new(0.3, -0.2, 0.93).normalize();
        (0..n).map(|_| grid.estimate_integral(probe, wo, &UniformlySampledLobe, rng.next_vec2()) as f64).sum::<f64>()
            / n as f64
    };
    let mut rng = crate::Pcg32::new(8, 8);
    let stratified = estimate(IntegralEstimator::StratifiedPatches, &mut rng, 4000);
    let sampled = estimate(IntegralEstimator::BsdfSampled, &mut rng, 400_000);
    assert!((sampled / stratified - 1.0).abs() < 0.01, "sampled {sampled} vs stratified {stratified}");
    // A Lambertian BSDF takes the exact sum under either.
    let lambertian = crate::Lambertian { normal: Vec3::Z, albedo: 0.5 };
    let (grid, probe) = one_probe(HemisphereGridSettings::default());
    let exact = grid.estimate_integral(probe, Vec3::Z, &lambertian, Vec2::ZERO);
    assert!((exact - 0.5 * grid.settings().initial_q).abs() < 1e-6 * exact.max(1e-30), "{exact}");
}

/// Two grids built alike over the same triangles locate alike (bidirectional guiding then
/// locates once for Q and W), and find the same probe everywhere; a grid of other probes
/// does not.
#[test]
fn grids_built_alike_locate_alike() {
    let floor = [
        crate::Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(-1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0)),
        crate::Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0)),
    ];
    let settings = HemisphereGridSettings { probe_count: Some(20), ..Default::default() };
    let q = HemisphereGrid::build(&floor, settings).unwrap();
    let mut w = HemisphereGrid::build(&floor, settings).unwrap();
    // Learning moves no probe.
    let probe = w.locate(Vec3::ZERO, Vec3::Y).unwrap();
    w.update(probe, Vec3::Y, 1.0);
    w.rebuild_sampling();
    assert!(q.locates_alike(&w) && w.locates_alike(&q));
    let mut rng = crate::Pcg32::new(4, 1);
    for _ in 0..1000 {
        let p = Vec3::new(rng.next_f32() * 2.0 - 1.0, 0.0, rng.next_f32() * 2.0 - 1.0);
        assert_eq!(q.locate(p, Vec3::Y), w.locate(p, Vec3::Y));
    }
    let other = HemisphereGrid::build(&floor, HemisphereGridSettings { probe_count: Some(30), ..settings }).unwrap();
    assert!(!q.locates_alike(&other));
}
