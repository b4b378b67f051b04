//! The spatial × directional tree's own tests: learning, density independence,
//! refinement in space and direction, the split rules, bad input.

use super::*;
use crate::distribution::DirectionalDistribution;
use crate::low_discrepancy::Pcg32;

fn tree(settings: SpatialDirectionalTreeSettings) -> SpatialDirectionalTree {
    SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).expect("a tree over the box")
}

/// Teaches a radiance field: 0.1 everywhere and `peak` within `width` (cos) of
/// `light`, through directions drawn by `draw` (returning direction and pdf).
fn teach(
    tree: &SpatialDirectionalTree,
    region: TreeRegion,
    light: Vec3,
    samples: u32,
    rng: &mut Pcg32,
    mut draw: impl FnMut(&mut Pcg32) -> (Vec3, f32),
) {
    for _ in 0..samples {
        let (d, pdf) = draw(rng);
        let target = if d.dot(light) > 0.999 { 100.0 } else { 0.1 };
        tree.update_sampled(region, d, target, pdf);
    }
}

/// Teaches `region` a radiance field of 0.1 everywhere and `peak` within `cos_within` of
/// `light`, through directions the region's own distribution draws: `rounds` epochs of
/// `per_round` records, each epoch sampled from the tree as the last refit left it.
pub(crate) fn teach_peak_by_own_samples(
    tree: &mut SpatialDirectionalTree,
    region: TreeRegion,
    (light, cos_within, peak): (Vec3, f32, f32),
    (rounds, per_round): (u32, u32),
    rng: &mut Pcg32,
) {
    for _ in 0..rounds {
        let snapshot = tree.clone();
        let d = snapshot.distribution(region);
        for _ in 0..per_round {
            let s = d.sample(rng.next_vec2());
            let target = if s.direction.dot(light) > cos_within { peak } else { 0.1 };
            tree.update_sampled(region, s.direction, target, s.pdf);
        }
        tree.rebuild_sampling();
    }
}

#[test]
fn learned_flux_does_not_depend_on_the_density_that_drew_the_directions() {
    // Bug 2 of the guiding issue: the same radiance field learned through mixtures
    // that sample the guide with probability 0.1 and 0.9 (the rest cosine-weighted)
    // must give the same Q within noise.
    // Fitted to the mean (the flux then the exact one) and to the root mean square.
    for second_moment in [false, true] {
        learns_alike_at_both_densities(second_moment);
    }
}

fn learns_alike_at_both_densities(second_moment: bool) {
    let light = Vec3::new(0.5, 0.0, 0.866).normalize();
    let mut learned = Vec::new();
    for p_guide in [0.1f32, 0.9] {
        let mut tree = tree(SpatialDirectionalTreeSettings { second_moment, ..Default::default() });
        let region = tree.locate(Vec3::ZERO, Vec3::Z).unwrap();
        let mut rng = Pcg32::new(11, 3);
        for _ in 0..6 {
            let frame = Frame::from_normal(Vec3::Z);
            let snapshot = tree.clone();
            let d = snapshot.distribution(region);
            teach(&tree, region, light, 200_000, &mut rng, |rng| {
                let u = rng.next_vec2();
                let wi = if rng.next_f32() < p_guide {
                    d.sample(u).direction
                } else {
                    let r = libm::sqrtf(u.x);
                    let phi = 2.0 * PI * u.y;
                    frame.to_world(Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), libm::sqrtf(1.0 - u.x)))
                };
                let cosine = wi.z.max(0.0) / PI;
                (wi, p_guide * d.pdf(wi) + (1.0 - p_guide) * cosine)
            });
            tree.rebuild_sampling();
        }
        // The exact flux: 0.1 over the hemisphere plus 99.9 over the cap.
        let cap = 2.0 * PI * (1.0 - 0.999);
        let exact = 0.1 * 2.0 * PI + 99.9 * cap;
        let flux = tree.leaf_flux(region.leaf);
        // Cells across the cap's rim hold the RMS of 0.1 and 100: more than the mean.
        let tolerance = if second_moment { 0.15 } else { 0.05 };
        assert!((flux / exact - 1.0).abs() < tolerance, "p_guide {p_guide}: flux {flux}, exact {exact}");
        learned.push((tree.q(region, light), tree.q(region, Vec3::new(-0.6, 0.0, 0.8))));
    }
    let (a, b) = (learned[0], learned[1]);
    assert!((a.0 / b.0 - 1.0).abs() < 0.1, "Q at the light: {} against {}", a.0, b.0);
    assert!((a.1 / b.1 - 1.0).abs() < 0.1, "Q off the light: {} against {}", a.1, b.1);
}

#[test]
fn a_narrow_source_is_resolved_far_below_one_degree() {
    let mut tree = tree(SpatialDirectionalTreeSettings::default());
    let region = tree.locate(Vec3::ZERO, Vec3::Z).unwrap();
    // A source 0.5° across: cos > 0.99996.
    let light = Vec3::new(0.3, 0.2, 0.9).normalize();
    let mut rng = Pcg32::new(5, 5);
    teach_peak_by_own_samples(&mut tree, region, (light, 0.99996, 1e4), (10, 100_000), &mut rng);
    let depth = tree.directional_depth(region.leaf);
    assert!(depth >= 9, "depth {depth}");
    // The guide's density at the source against the cosine density there.
    let pdf = tree.distribution(region).pdf(light);
    assert!(pdf > 1000.0 * light.z / PI, "pdf at the source {pdf}");
}

#[test]
fn busy_leaves_split_and_regions_follow_space() {
    let mut tree = tree(SpatialDirectionalTreeSettings { min_split_records: 100, ..Default::default() });
    let mut rng = Pcg32::new(1, 9);
    for _ in 0..4 {
        for _ in 0..50_000 {
            let p = Vec3::new(rng.next_f32() * 0.5 - 1.0, -1.0, rng.next_f32() * 0.5 - 1.0);
            let region = tree.locate(p, Vec3::Y).unwrap();
            tree.update(region, Vec3::Y, 1.0);
        }
        tree.rebuild_sampling();
        assert!(tree.validate().is_ok());
    }
    assert!(tree.leaf_count() > 8, "{} leaves", tree.leaf_count());
    let a = tree.locate(Vec3::new(-0.9, -1.0, -0.9), Vec3::Y).unwrap();
    let b = tree.locate(Vec3::new(0.9, 1.0, 0.9), Vec3::Y).unwrap();
    assert_ne!(a.leaf, b.leaf);
}

#[test]
fn leaves_whose_normals_disagree_split_whatever_their_count() {
    // A corner: a floor (normal +y) and a wall (normal +x) share the one leaf of a
    // single spatial tree, with far too few records for the count rule (c huge) to
    // split it.
    let corner = |share: f32, normals: [Vec3; 2]| {
        let settings = SpatialDirectionalTreeSettings {
            spatial_threshold: 1e6,
            min_split_records: 100,
            mixed_normal_share: share,
            trees_per_axis: false,
            ..Default::default()
        };
        let mut tree = tree(settings);
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..3 {
            for i in 0..2000 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let normal = normals[i % 2];
                let region = tree.locate(p, normal).unwrap();
                tree.update_sampled(region, normal, 1.0, 1.0);
            }
            tree.rebuild_sampling();
            tree.validate().unwrap();
        }
        tree.leaf_count()
    };
    // One split per refit while mixed: 2, 4, then 8 leaves (each half stays a corner).
    assert_eq!(corner(0.97, [Vec3::Y, Vec3::X]), 8);
    assert_eq!(corner(0.0, [Vec3::Y, Vec3::X]), 1, "0 turns the rule off");
    // One surface, or off-axis normals of one slope, are not mixed.
    assert_eq!(corner(0.97, [Vec3::Y, Vec3::Y]), 1);
    let slope = [Vec3::new(0.0, 0.8, 0.6), Vec3::new(0.6, 0.8, 0.0)];
    assert_eq!(corner(0.97, slope), 1);
}

#[test]
fn trees_per_axis_keep_a_corners_surfaces_apart() {
    // The same corner with a spatial tree per axis: the floor's records reach the
    // y tree and the wall's the x tree, so no leaf is mixed and none splits, and each
    // surface samples the half of a square built around its own normal.
    let settings = SpatialDirectionalTreeSettings {
        spatial_threshold: 1e6,
        min_split_records: 100,
        trees_per_axis: true,
        ..Default::default()
    };
    let mut tree = tree(settings);
    assert_eq!(tree.leaf_count(), 3);
    let mut rng = Pcg32::new(4, 4);
    for _ in 0..3 {
        for i in 0..2000 {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let normal = [Vec3::Y, Vec3::X][i % 2];
            let region = tree.locate(p, normal).unwrap();
            tree.update_sampled(region, normal, 1.0, 1.0);
        }
        tree.rebuild_sampling();
        tree.validate().unwrap();
    }
    assert_eq!(tree.leaf_count(), 3);
    for (normal, axis) in [(Vec3::Y, 1), (-Vec3::X, 0), (Vec3::new(0.3, 0.2, -0.93).normalize(), 2)] {
        let region = tree.locate(Vec3::splat(0.1), normal).unwrap();
        assert_eq!(tree.leaf_axis(region.leaf), Some(axis), "normal {normal}");
    }
    let floor = tree.locate(Vec3::ZERO, Vec3::Y).unwrap();
    // The floor learned only its normal's direction: its half samples near it.
    let d = tree.distribution(floor);
    assert!(d.pdf(Vec3::Y) > 3.0 * d.pdf(Vec3::new(0.0, 0.5, 0.866)), "{}", d.pdf(Vec3::Y));
    assert_eq!(d.pdf(-Vec3::Y), 0.0);
}

#[test]
fn bounds_without_a_finite_extent_are_refused_and_flat_ones_validate() {
    // Found by the capi_calls fuzzer: huge bounds made a tree that failed validation.
    let settings = SpatialDirectionalTreeSettings::default();
    let huge = SpatialDirectionalTree::new(Vec3::splat(-3e38), Vec3::splat(3e38), settings);
    assert!(matches!(huge, Err(Error::InvalidSetting { name: "bounds", .. })));
    let flat = SpatialDirectionalTree::new(Vec3::ONE, Vec3::ONE, settings).unwrap();
    flat.validate().unwrap();
}

#[test]
fn reset_forgets_every_record_and_split() {
    let mut tree = tree(SpatialDirectionalTreeSettings { min_split_records: 100, ..Default::default() });
    let mut rng = Pcg32::new(2, 5);
    for _ in 0..4 {
        for _ in 0..4000 {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let region = tree.locate(p, Vec3::Z).unwrap();
            tree.update_sampled(region, Vec3::Z, 1.0, 1.0);
        }
        tree.rebuild_sampling();
    }
    assert!(tree.leaf_count() > 1);
    tree.reset();
    assert_eq!((tree.leaf_count(), tree.directional_node_count(), tree.stats().accepted_updates), (1, 1, 0));
    tree.validate().unwrap();
    // With a tree per axis: one leaf and one directional root for each.
    let settings = SpatialDirectionalTreeSettings { trees_per_axis: true, ..Default::default() };
    let mut per_axis = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
    per_axis.reset();
    assert_eq!((per_axis.leaf_count(), per_axis.directional_node_count()), (3, 3));
    tree.validate().unwrap();
    let region = tree.locate(Vec3::ZERO, Vec3::Z).unwrap();
    let uniform = tree.pdf(region, Vec3::new(0.3, 0.2, 0.9).normalize());
    assert!((uniform - tree.pdf(region, Vec3::Z)).abs() < 1e-6, "a fresh tree samples uniformly");
}

#[test]
fn bad_records_are_counted_or_ignored() {
    let tree = tree(SpatialDirectionalTreeSettings::default());
    let region = tree.locate(Vec3::ZERO, Vec3::Z).unwrap();
    assert_eq!(tree.update_sampled(region, Vec3::Z, f32::NAN, 1.0), UpdateOutcome::RejectedNonFinite);
    assert_eq!(tree.update_sampled(region, Vec3::Z, -1.0, 1.0), UpdateOutcome::RejectedNegative);
    assert_eq!(tree.update_sampled(region, Vec3::Z, 1.0, 0.0), UpdateOutcome::OutsideDomain);
    assert_eq!(tree.update_sampled(region, Vec3::new(2.0, 0.0, 0.0), 1.0, 1.0), UpdateOutcome::OutsideDomain);
    let stray = TreeRegion { leaf: 99, normal: Vec3::Z, upper_half: false };
    assert_eq!(tree.update_sampled(stray, Vec3::Z, 1.0, 1.0), UpdateOutcome::OutsideDomain);
    let stats = tree.stats();
    assert_eq!((stats.rejected_non_finite, stats.rejected_negative, stats.accepted_updates), (1, 1, 0));
    assert!(tree.locate(Vec3::splat(f32::NAN), Vec3::Z).is_none());
}

#[test]
fn settings_out_of_range_are_refused() {
    let bad = [
        SpatialDirectionalTreeSettings { flux_fraction: 0.0, ..Default::default() },
        SpatialDirectionalTreeSettings { max_directional_depth: 21, ..Default::default() },
        SpatialDirectionalTreeSettings { uniform_mix: 1.5, ..Default::default() },
        SpatialDirectionalTreeSettings { spatial_threshold: f32::NAN, ..Default::default() },
    ];
    for settings in bad {
        assert!(SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, settings).is_err(), "{settings:?}");
    }
    let tiny = SpatialDirectionalTreeSettings { budget_bytes: 16, ..Default::default() };
    assert!(matches!(SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, tiny), Err(Error::BudgetTooSmall { .. })));
    // The second moment with an integral read from Q is refused by name; the mean fit
    // takes any integral.
    let rule = UpdateRule { integral: crate::update_rule::IntegralEstimator::BsdfSampled, ..Default::default() };
    let from_q = SpatialDirectionalTreeSettings { update_rule: rule, ..Default::default() };
    let refused = SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, from_q);
    assert!(matches!(refused, Err(Error::InvalidSetting { name: "second_moment", .. })));
    let mean = SpatialDirectionalTreeSettings { second_moment: false, ..from_q };
    assert!(SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, mean).is_ok());
    // The defaults taken to a rule keep the second moment only under the path's
    // continuation, so they are valid with any rule.
    let defaults = SpatialDirectionalTreeSettings::default();
    assert!(!defaults.with_update_rule(rule).second_moment);
    assert!(SpatialDirectionalTree::new(Vec3::ZERO, Vec3::ONE, defaults.with_update_rule(rule)).is_ok());
    let path = UpdateRule { integral: crate::update_rule::IntegralEstimator::PathContinuation, ..rule };
    assert!(defaults.with_update_rule(path).second_moment);
    assert!(!SpatialDirectionalTreeSettings { second_moment: false, ..defaults }.with_update_rule(path).second_moment);
}

#[test]
fn the_second_moment_gives_rare_bright_arrivals_more_samples_than_their_mean() {
    // Two halves of the sphere with the same mean radiance 1: toward +x it arrives as
    // 100 once in a hundred, toward −x always as 1. Fitted to the mean both halves
    // are sampled alike; fitted to the root mean square, +x ten times as densely.
    let ratio = |second_moment: bool| {
        let settings = SpatialDirectionalTreeSettings { second_moment, uniform_mix: 0.0, ..Default::default() };
        let mut tree = tree(settings);
        let region = tree.locate(Vec3::ZERO, Vec3::Z).unwrap();
        let mut rng = Pcg32::new(8, 3);
        for _ in 0..4 {
            for _ in 0..200_000 {
                let u = rng.next_vec2();
                let z = 1.0 - 2.0 * u.x;
                let r = libm::sqrtf((1.0 - z * z).max(0.0));
                let phi = 2.0 * PI * u.y;
                let d = Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z);
                let target = if d.x > 0.0 {
                    if rng.next_f32() < 0.01 {
                        100.0
                    } else {
                        0.0
                    }
                } else {
                    1.0
                };
                tree.update_sampled(region, d, target, 1.0 / SQUARE_TO_SOLID_ANGLE);
            }
            tree.rebuild_sampling();
        }
        let d = tree.distribution(region);
        let (bright, steady) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8));
        (d.pdf(bright) / d.pdf(steady), tree.q(region, bright))
    };
    let (mean, q_mean) = ratio(false);
    let (moment, q_rms) = ratio(true);
    assert!((0.7..1.4).contains(&mean), "fitted to the mean: {mean}");
    assert!((6.0..16.0).contains(&moment), "fitted to the second moment: {moment}");
    // Q is the mean radiance (1) or the root mean square (10) there.
    assert!((q_mean - 1.0).abs() < 0.3 && (q_rms - 10.0).abs() < 3.0, "Q {q_mean}, {q_rms}");
}
