//! The irradiance volume's own tests: learning, splitting, folding, the integral estimates.

use super::*;
use crate::distribution::DirectionalDistribution;
use crate::low_discrepancy::Pcg32;
use crate::validation::{chi_square_test, pdf_integral, ChiSquareSettings};
use crate::volume::SphereLayout;

fn volume(budget_bytes: usize) -> IrradianceVolume {
    let settings = IrradianceVolumeSettings { budget_bytes, ..Default::default() };
    IrradianceVolume::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0), settings).unwrap()
}

/// Bug 2 of the guiding issue, as for the hemisphere grid: Q learned through mixtures
/// that sample the volume with probability 0.1 and 0.9 (the rest cosine-weighted about
/// the normal) is each patch's mean over its solid angle. The field is bright within
/// 0.02 of the horizon, inside the band just above it.
#[test]
fn learned_q_does_not_depend_on_the_density_that_drew_the_directions() {
    let radiance = |d: Vec3| if d.z < 0.02 { 50.0 } else { 1.0 };
    let layout = SphereLayout::default();
    let horizon = layout.patch_of(Vec3::new(0.999, 0.0, 0.01)).unwrap();
    let point = Vec3::splat(0.5);
    let q = |p_guide: f32, weighted: bool| {
        let mut guide = volume(64 << 10);
        let mut rng = Pcg32::new(9, 2);
        for _ in 0..4 {
            let region = guide.locate(point, Vec3::Z).unwrap();
            let d = guide.distribution(region);
            for _ in 0..250_000 {
                let (wi, pdf) = crate::validation::sample_guide_or_cosine(&d, p_guide, &mut rng);
                if weighted {
                    guide.update_sampled(region, wi, radiance(wi), pdf);
                } else {
                    guide.update(region, wi, radiance(wi));
                }
            }
            // Splits too: the children share the parent's weights.
            guide.rebuild_sampling();
        }
        guide.q(guide.locate(point, Vec3::Z).unwrap().leaf, horizon) as f64
    };
    // The band's mean: 50 over 0.02 of its 0.125 in z (uniform in solid angle), 1 above.
    let exact = (0.02 * 50.0 + 0.105) / 0.125;
    crate::q_table::assert_learning_ignores_the_density(q, exact);
}

#[test]
fn busy_leaves_split_within_the_budget_and_children_inherit_q() {
    let mut guide = volume(200 << 10);
    let leaves = guide.leaf_count();
    let hot = Vec3::new(0.3, 0.3, 0.3);
    let region = guide.locate(hot, Vec3::Y).unwrap();
    let mut rng = Pcg32::new(2, 2);
    for round in 0..12 {
        for _ in 0..20_000 {
            let region = guide.locate(hot + 0.05 * (rng.next_vec2().extend(rng.next_f32()) - 0.5), Vec3::Y).unwrap();
            let d = guide.sample(region, rng.next_vec2()).direction;
            guide.update(region, d, 1.0 + d.x.max(0.0));
        }
        guide.rebuild_sampling();
        assert!(guide.memory_bytes() <= 200 << 10, "round {round}: {} bytes", guide.memory_bytes());
        assert!(guide.validate().is_ok());
    }
    assert!(guide.leaf_count() > leaves, "no leaf split");
    // The busy corner is now covered by a smaller leaf than the one it started in,
    // whose table still knows what its ancestors learned.
    let child = guide.locate(hot, Vec3::Y).unwrap();
    assert!(child.leaf != region.leaf || guide.node_count() > leaves);
    let x = guide.settings().layout.patch_of(Vec3::new(0.9, 0.3, 0.3)).unwrap();
    assert!(guide.q(child.leaf, x) > 1.5, "{}", guide.q(child.leaf, x));
    // A far corner nobody visited kept one leaf.
    let far = guide.locate(Vec3::new(1.9, 0.9, 0.9), Vec3::Y).unwrap();
    assert_eq!(guide.q(far.leaf, x), guide.settings().initial_q);
}

#[test]
fn splits_pending_foretells_the_rebuild_and_capacity_bounds_the_growth() {
    let mut guide = volume(160 << 10);
    let (max_leaves, max_nodes) = guide.capacity();
    assert!(max_leaves > guide.leaf_count() && max_nodes > guide.node_count());
    let mut rng = Pcg32::new(7, 7);
    let mut splits = 0;
    for _ in 0..10 {
        assert!(!guide.splits_pending() || guide.capacity().0 > guide.leaf_count());
        for _ in 0..30_000 {
            let p = Vec3::new(0.2, 0.2, 0.2) + 0.1 * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let region = guide.locate(p, Vec3::Y).unwrap();
            let d = guide.sample(region, rng.next_vec2()).direction;
            guide.update(region, d, 1.0);
        }
        let (pending, leaves) = (guide.splits_pending(), guide.leaf_count());
        let copy = guide.clone();
        guide.rebuild_sampling();
        assert_eq!(pending, guide.leaf_count() > leaves);
        splits += pending as u32;
        assert!(guide.leaf_count() <= max_leaves && guide.node_count() <= max_nodes);
        // A clone rebuilds to the same state as the original.
        let mut copy = copy;
        copy.rebuild_sampling();
        assert_eq!(copy.to_bytes(), guide.to_bytes());
    }
    assert!(splits > 0, "no leaf split");
}

#[test]
fn folding_keeps_the_pdf_exact_on_the_normals_side() {
    let mut guide = volume(64 << 10);
    let normal = Vec3::new(0.3, 0.8, -0.52).normalize();
    let region = guide.locate(Vec3::splat(0.5), normal).unwrap();
    let mut rng = Pcg32::new(5, 5);
    let values: Vec<f32> = (0..guide.patch_count()).map(|_| rng.next_f32() * 3.0).collect();
    guide.set_q_values(region.leaf, &values);
    guide.rebuild_sampling();
    let distribution = guide.distribution(region);
    let total = pdf_integral(&|d| distribution.pdf(d), normal, 64, 6);
    assert!((total - 1.0).abs() < 1e-3, "∫ = {total}");
    let report = chi_square_test(&distribution, normal, &ChiSquareSettings::default());
    assert!(report.passes(0.01), "{report:?}");
    assert_eq!(distribution.pdf(-normal), 0.0);
}

#[test]
fn the_lambertian_estimate_sees_only_the_upper_hemisphere() {
    let mut guide = volume(64 << 10);
    let region = guide.locate(Vec3::splat(0.5), Vec3::Z).unwrap();
    // Q = 1 above the xy plane, 100 below: a Lambertian at +z sees ≈ albedo·1.
    let layout = guide.settings().layout;
    let values: Vec<f32> = (0..guide.patch_count())
        .map(|k| if layout.direction_in_patch(k, Vec2::splat(0.5)).z > 0.0 { 1.0 } else { 100.0 })
        .collect();
    guide.set_q_values(region.leaf, &values);
    guide.rebuild_sampling();
    let bsdf = crate::scattering::Lambertian { normal: Vec3::Z, albedo: 0.5 };
    let estimate = guide.estimate_integral(region, Vec3::Z, &bsdf, Vec2::splat(0.5));
    assert!((estimate - 0.5).abs() < 0.02, "{estimate}");
}
