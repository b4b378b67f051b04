//! The property suite every [`Guide`] must pass, written once and instantiated per
//! structure (and layout) by `guide_properties!`:
//!
//! - the pdf integrates to one for flat, random and extreme (1e-30…1e30) tables;
//! - chi-square goodness of fit of `sample` against `pdf` (1e6 samples, Šidák-corrected
//!   0.01), and a deliberately wrong pdf fails it;
//! - update streams of any f32 (NaN, ±∞, negative, 1e±30) keep every Q finite and above
//!   the floor, and rejections are counted;
//! - concurrent updates from several threads lose no visit;
//! - for tables (`table_rule_properties!`): α = 0 keeps Q, α = 1 replaces it,
//!   α = 1/(1+n) converges to the targets' mean, and concurrent updates tear no value;
//! - memory stays within the byte budget while the guide learns (and splits, where it
//!   adapts);
//! - serialization round-trips exactly; truncated, bit-flipped or re-sealed damaged
//!   buffers give an error or a valid guide, never a panic.

mod support;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{Vec2, Vec3};
use guiding_core::validation::{chi_square_test, pdf_integral, sidak_significance, ChiSquareSettings};
use guiding_core::{
    DirectionalDistribution, Frame, Guide, HemisphereMapping, IntegralEstimator, LearningRate, Pcg32,
    UniformHemisphere, UpdateOutcome, UpdateRule,
};
use proptest::prelude::*;
use support::{GuideAccess, RotatedPdf, TableAccess};

fn rule(learning_rate: LearningRate) -> UpdateRule {
    UpdateRule { learning_rate, integral: IntegralEstimator::BsdfWeightedSum }
}

/// A table learned from a synthetic radiance field: a bright lobe around `light` on a
/// dim background, taught by uniformly sampled directions.
fn learn_lobe<G: GuideAccess>(guide: &G, region: G::Region, normal: Vec3, light: Vec3, rng: &mut Pcg32) {
    let hemisphere = UniformHemisphere::new(normal);
    for _ in 0..20_000 {
        let d = hemisphere.sample(rng.next_vec2()).direction;
        let radiance = 0.05 + 20.0 * d.dot(light).max(0.0).powi(16);
        guide.update(region, d, radiance);
    }
}

/// Tables spanning 1e-30…1e30, log-uniform.
fn extreme_table(entries: usize, rng: &mut Pcg32) -> Vec<f32> {
    (0..entries).map(|_| 10f32.powf(rng.next_f32() * 60.0 - 30.0)).collect()
}

/// Flat, random, learned and extreme tables, each set on every test region and rebuilt.
fn table_cases<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) -> Vec<(String, G)> {
    let mut rng = Pcg32::new(42, 7);
    let mut cases = Vec::new();
    let flat = make(UpdateRule::default());
    cases.push(("flat".to_string(), flat));
    let mut random = make(UpdateRule::default());
    for (region, _) in random.test_regions() {
        let values: Vec<f32> = (0..random.entry_count()).map(|_| rng.next_f32() * 4.0).collect();
        random.set_entries(region, &values);
    }
    cases.push(("random".to_string(), random));
    let learned = make(UpdateRule::default());
    for (region, normal) in learned.test_regions() {
        let light = (normal + Vec3::new(0.6, 0.3, -0.5)).normalize();
        learn_lobe(&learned, region, normal, light, &mut rng);
    }
    cases.push(("learned".to_string(), learned));
    let mut extreme = make(UpdateRule::default());
    for (region, _) in extreme.test_regions() {
        let values = extreme_table(extreme.entry_count(), &mut rng);
        extreme.set_entries(region, &values);
    }
    cases.push(("extreme".to_string(), extreme));
    for (_, guide) in &mut cases {
        guide.rebuild_sampling();
    }
    cases
}

fn check_normalization<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) {
    for (name, guide) in table_cases(make) {
        for (region, normal) in guide.test_regions() {
            let distribution = guide.distribution(region);
            let total = pdf_integral(&|d| distribution.pdf(d), normal, 64, guide.integration_depth());
            assert!((total - 1.0).abs() < 1e-3, "{name} table: pdf integrates to {total}");
        }
    }
}

fn check_chi_square<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) {
    let cases = table_cases(make);
    let tests = (cases.len() * cases[0].1.test_regions().len()) as u32;
    let significance = sidak_significance(0.01, tests);
    for (case, (name, guide)) in cases.iter().enumerate() {
        for (index, (region, normal)) in guide.test_regions().into_iter().enumerate() {
            // Šidák assumes independent tests: every case draws its own uniform stream.
            let settings = ChiSquareSettings { seed: (case * 16 + index) as u64 + 1, ..Default::default() };
            let report = chi_square_test(&guide.distribution(region), normal, &settings);
            assert!(report.passes(significance), "{name} table, region {region:?}: {report:?}");
        }
    }
}

fn check_broken_pdf_fails<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) {
    let cases = table_cases(make);
    let (_, learned) = cases.iter().find(|(name, _)| name == "learned").expect("learned case");
    for (region, normal) in learned.test_regions() {
        // The sampler is right; only the pdf is turned by 30° about the normal.
        let broken = RotatedPdf { inner: learned.distribution(region), frame: Frame::from_normal(normal), angle: 0.52 };
        let report = chi_square_test(&broken, normal, &ChiSquareSettings::default());
        assert!(!report.passes(0.01), "a rotated pdf must fail: {report:?}");
        assert!(report.p_value < 1e-6, "{report:?}");
    }
}

fn arbitrary_target() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(-0.0f32),
        Just(0.0f32),
        Just(1e-30f32),
        Just(1e30f32),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        -1e30f32..0.0,
        0.0f32..1e30,
        any::<f32>(),
    ]
}

fn arbitrary_direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        4 => (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z).normalize_or(Vec3::Y)),
        1 => Just(Vec3::NAN),
        1 => Just(Vec3::ZERO),
    ]
}

fn check_update_stream<G: GuideAccess>(guide: &G, stream: &[(f32, Vec3)]) -> Result<(), TestCaseError> {
    let (region, _) = guide.test_regions()[0];
    let before = guide.stats();
    let (mut non_finite, mut negative) = (0, 0);
    for &(target, direction) in stream {
        match guide.update(region, direction, target) {
            UpdateOutcome::RejectedNonFinite => non_finite += 1,
            UpdateOutcome::RejectedNegative => negative += 1,
            UpdateOutcome::Accepted | UpdateOutcome::OutsideDomain => {}
            other => return Err(TestCaseError::fail(format!("an outcome this suite does not know: {other:?}"))),
        }
    }
    let after = guide.stats();
    prop_assert_eq!(after.rejected_negative - before.rejected_negative, negative);
    prop_assert_eq!(after.rejected_non_finite - before.rejected_non_finite, non_finite);
    let expected_non_finite = stream.iter().filter(|(t, _)| !t.is_finite()).count() as u64;
    let expected_negative = stream.iter().filter(|(t, _)| t.is_finite() && *t < 0.0).count() as u64;
    prop_assert_eq!((non_finite, negative), (expected_non_finite, expected_negative));
    prop_assert!(guide.all_values().iter().all(|q| q.is_finite() && *q >= guide.floor()));
    prop_assert!(guide.validate().is_ok());
    Ok(())
}

fn check_rates_zero_and_one<G: TableAccess>(make: &impl Fn(UpdateRule) -> G) {
    let keep = make(rule(LearningRate::Exponential { alpha: 0.0 }));
    let replace = make(rule(LearningRate::Exponential { alpha: 1.0 }));
    let mut rng = Pcg32::new(3, 3);
    for (region, normal) in keep.test_regions() {
        let hemisphere = UniformHemisphere::new(normal);
        for _ in 0..1000 {
            let d = hemisphere.sample(rng.next_vec2()).direction;
            let before = keep.entry_value(region, d);
            let target = rng.next_f32() * 100.0;
            assert_eq!(keep.update(region, d, target), UpdateOutcome::Accepted);
            assert_eq!(keep.entry_value(region, d), before, "α = 0 changed Q");
            assert_eq!(replace.update(region, d, target), UpdateOutcome::Accepted);
            assert_eq!(replace.entry_value(region, d), target.max(replace.floor()), "α = 1 did not replace Q");
        }
    }
}

fn check_simple_average_converges<G: TableAccess>(make: &impl Fn(UpdateRule) -> G) {
    let guide = make(rule(LearningRate::SimpleAverage));
    let (region, normal) = guide.test_regions()[1];
    let direction = (normal + Vec3::new(0.2, 0.1, 0.3)).normalize();
    // A stationary, skewed target distribution: exponential with mean 2.5.
    let mut rng = Pcg32::new(5, 5);
    for _ in 0..100_000 {
        let target = -2.5 * (1.0 - rng.next_f32()).ln();
        guide.update(region, direction, target);
    }
    let q = guide.entry_value(region, direction);
    assert!((q - 2.5).abs() < 0.025, "Q = {q} after 1e5 updates, mean 2.5");
}

/// Updates one region from four threads at once, targets 1 and 3 alternating, and
/// checks no visit was lost; returns the guide for structure-specific checks.
fn check_concurrent_updates<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) -> G {
    let guide = make(rule(LearningRate::SimpleAverage));
    let (region, normal) = guide.test_regions()[0];
    let before = guide.stats().accepted_updates;
    let (threads, per_thread) = (4u64, 50_000u64);
    let accepted = AtomicU64::new(0);
    std::thread::scope(|scope| {
        for t in 0..threads {
            let (guide, accepted) = (&guide, &accepted);
            scope.spawn(move || {
                let mut rng = Pcg32::new(100 + t, t);
                let hemisphere = UniformHemisphere::new(normal);
                for i in 0..per_thread {
                    let target = if i % 2 == 0 { 1.0 } else { 3.0 };
                    let d = hemisphere.sample(rng.next_vec2()).direction;
                    if guide.update(region, d, target) == UpdateOutcome::Accepted {
                        accepted.fetch_add(1, Ordering::Relaxed);
                    }
                }
            });
        }
    });
    assert_eq!(accepted.load(Ordering::Relaxed), threads * per_thread);
    assert_eq!(guide.stats().accepted_updates - before, threads * per_thread, "visits lost");
    assert!(guide.validate().is_ok());
    assert!(guide.all_values().iter().all(|q| q.is_finite() && *q >= guide.floor()));
    guide
}

/// With only targets 1 and 3 in play, any other Q in a table is a torn write.
fn check_no_torn_values<G: TableAccess>(make: &impl Fn(UpdateRule) -> G) {
    let guide = check_concurrent_updates(make);
    let initial = make(UpdateRule::default()).all_values()[0];
    for q in guide.all_values() {
        assert!(q == initial || (1.0..=3.0).contains(&q), "torn or stray value {q}");
    }
}

/// Builds the guide at several budgets and teaches it pass after pass around one busy
/// corner of the box (where adaptive structures split): its memory never exceeds the
/// budget.
fn check_memory_within_budget<G: GuideAccess>() {
    for budget in [48 << 10, 200 << 10, 1 << 20, 2 << 20] {
        let mut guide = G::with_budget(budget);
        let mut rng = Pcg32::new(budget as u64, 3);
        for pass in 0..10 {
            for _ in 0..30_000 {
                let corner = Vec3::new(-0.8, -1.0, -0.8) + 0.4 * Vec3::new(rng.next_f32(), 0.0, rng.next_f32());
                let Some(region) = guide.locate(corner, Vec3::Y) else { continue };
                let sample = guide.sample(region, rng.next_vec2());
                let target = 0.1 + 10.0 * sample.direction.x.max(0.0);
                guide.update_sampled(region, sample.direction, target, sample.pdf);
            }
            guide.rebuild_sampling();
            let bytes = guide.stats().memory_bytes;
            assert!(bytes <= budget, "budget {budget}, pass {pass}: {bytes} bytes");
            assert!(guide.validate().is_ok());
        }
    }
}

fn check_round_trip<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) {
    for (name, guide) in table_cases(make) {
        let bytes = guide.to_bytes();
        let loaded = G::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(loaded.to_bytes(), bytes, "{name}: bytes differ after a round trip");
        assert_eq!(loaded.stats(), guide.stats(), "{name}");
        assert_eq!(loaded.test_regions(), guide.test_regions(), "{name}: regions moved");
        let mut rng = Pcg32::new(9, 9);
        for (region, _) in guide.test_regions() {
            for _ in 0..100 {
                let u = rng.next_vec2();
                assert_eq!(loaded.sample(region, u), guide.sample(region, u), "{name}: sampling changed");
            }
        }
    }
}

/// Merging: a fresh guide adds nothing to any table case, and a case merged with its own
/// saved copy stays valid and normalised, with twice the updates.
fn check_merge<G: GuideAccess>(make: &impl Fn(UpdateRule) -> G) {
    let mut rng = Pcg32::new(5, 5);
    for (name, guide) in table_cases(make) {
        let bytes = guide.to_bytes();
        let mut with_fresh = G::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        with_fresh.merge(&make(UpdateRule::default())).unwrap_or_else(|e| panic!("{name}: {e}"));
        // Regions are located anew: a merge may renumber them.
        for ((region, _), (merged, _)) in guide.test_regions().into_iter().zip(with_fresh.test_regions()) {
            for _ in 0..50 {
                let d = guide.sample(region, rng.next_vec2()).direction;
                let (before, after) = (guide.pdf(region, d), with_fresh.pdf(merged, d));
                assert!((before - after).abs() <= 1e-3 * before.max(1e-3), "{name}: pdf {before} became {after}");
            }
        }
        let mut doubled = G::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let copy = G::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        doubled.merge(&copy).unwrap_or_else(|e| panic!("{name}: {e}"));
        doubled.validate().unwrap_or_else(|e| panic!("{name}: merged with itself: {e}"));
        assert_eq!(doubled.stats().accepted_updates, 2 * guide.stats().accepted_updates, "{name}");
        for (region, normal) in doubled.test_regions() {
            let distribution = doubled.distribution(region);
            let total = pdf_integral(&|d| distribution.pdf(d), normal, 64, doubled.integration_depth());
            assert!((total - 1.0).abs() < 1e-3, "{name} merged with itself: pdf integrates to {total}");
        }
    }
}

fn check_damaged_buffer<G: GuideAccess>(
    bytes: &[u8],
    cut: usize,
    flips: &[(usize, u8)],
    reseal: bool,
) -> Result<(), TestCaseError> {
    let mut damaged = bytes[..cut.min(bytes.len())].to_vec();
    for &(position, bit) in flips {
        if !damaged.is_empty() {
            let i = position % damaged.len();
            damaged[i] ^= 1 << (bit % 8);
        }
    }
    if reseal && damaged.len() >= 8 {
        guiding_core::reseal_checksum(&mut damaged);
    }
    if let Ok(guide) = G::from_bytes(&damaged) {
        prop_assert!(guide.validate().is_ok());
        prop_assert!(guide.all_values().iter().all(|q| q.is_finite() && *q >= guide.floor()));
        // A surviving guide must still work.
        let survivors = guide.test_points().into_iter().filter_map(|(p, n)| guide.locate(p, n).map(|r| (r, n)));
        for (region, normal) in survivors {
            let s = guide.sample(region, Vec2::new(0.3, 0.6));
            prop_assert!(s.pdf.is_finite() && s.pdf >= 0.0);
            let _ = guide.update(region, normal, 1.0);
        }
    }
    Ok(())
}

macro_rules! guide_properties {
    ($module:ident, $guide:ty, $make:expr) => {
        mod $module {
            use super::*;

            fn make(rule: UpdateRule) -> $guide {
                ($make)(rule)
            }

            #[test]
            fn pdf_integrates_to_one_for_flat_random_learned_and_extreme_tables() {
                check_normalization(&make);
            }

            #[test]
            fn sampler_matches_pdf_chi_square() {
                check_chi_square(&make);
            }

            #[test]
            fn a_wrong_pdf_fails_chi_square() {
                check_broken_pdf_fails(&make);
            }

            #[test]
            fn concurrent_updates_lose_no_visit() {
                check_concurrent_updates(&make);
            }

            #[test]
            fn serialization_round_trips_exactly() {
                check_round_trip(&make);
            }

            #[test]
            fn merging_a_fresh_guide_changes_nothing_and_a_copy_doubles_the_updates() {
                check_merge(&make);
            }

            #[test]
            fn memory_stays_within_the_budget() {
                check_memory_within_budget::<$guide>();
            }

            proptest! {
                // Each case integrates a pdf over the sphere (≈ 0.2 s): fewer cases.
                #![proptest_config(ProptestConfig::with_cases(12))]

                #[test]
                fn random_tables_integrate_to_one(values in proptest::collection::vec(
                    prop_oneof![0.0f32..10.0, 1e-30f32..1e-20, 1e20f32..1e30], 1..=512)) {
                    let mut guide = make(UpdateRule::default());
                    let entries = guide.entry_count();
                    let (region, normal) = guide.test_regions()[0];
                    let table: Vec<f32> = (0..entries).map(|k| values[k % values.len()]).collect();
                    guide.set_entries(region, &table);
                    guide.rebuild_sampling();
                    let distribution = guide.distribution(region);
                    let depth = guide.integration_depth().min(4);
                    let total = pdf_integral(&|d| distribution.pdf(d), normal, 64, depth);
                    prop_assert!((total - 1.0).abs() < 1e-3, "integral {}", total);
                }
            }

            proptest! {
                #![proptest_config(ProptestConfig::with_cases(64))]

                #[test]
                fn any_update_stream_stays_finite_and_above_the_floor(
                    stream in proptest::collection::vec((arbitrary_target(), arbitrary_direction()), 1..400),
                    rate in prop_oneof![
                        Just(LearningRate::SimpleAverage),
                        Just(LearningRate::RegionVisits),
                        Just(LearningRate::Global { exponent: 0.8 }),
                        (0.0f32..=1.0).prop_map(|alpha| LearningRate::Exponential { alpha }),
                    ],
                ) {
                    let guide = make(rule(rate));
                    check_update_stream(&guide, &stream)?;
                }

                #[test]
                fn damaged_buffers_error_or_stay_valid(
                    cut in any::<usize>(),
                    flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..4),
                    reseal in any::<bool>(),
                ) {
                    thread_local! {
                        static BYTES: Vec<u8> = {
                            let mut guide = make(UpdateRule::default());
                            for (region, normal) in guide.test_regions() {
                                guide.update(region, normal, 2.0);
                            }
                            guide.rebuild_sampling();
                            guide.to_bytes()
                        };
                    }
                    BYTES.with(|bytes| {
                        // Mostly whole buffers with flipped bits, sometimes truncated ones.
                        let cut = if cut % 4 == 0 { cut % (bytes.len() + 1) } else { bytes.len() };
                        check_damaged_buffer::<$guide>(bytes, cut, &flips, reseal)
                    })?;
                }
            }
        }
    };
}

/// The Eq. (1) checks of guides whose entries take one target at a time.
macro_rules! table_rule_properties {
    ($module:ident, $guide:ty, $make:expr) => {
        mod $module {
            use super::*;

            fn make(rule: UpdateRule) -> $guide {
                ($make)(rule)
            }

            #[test]
            fn learning_rates_zero_and_one() {
                check_rates_zero_and_one(&make);
            }

            #[test]
            fn simple_average_converges_to_the_mean() {
                check_simple_average_converges(&make);
            }

            #[test]
            fn concurrent_updates_tear_no_value() {
                check_no_torn_values(&make);
            }
        }
    };
}

fn cylindrical(rule: UpdateRule) -> guiding_core::HemisphereGrid {
    support::hemisphere_grid(HemisphereMapping::Cylindrical, rule)
}

fn concentric(rule: UpdateRule) -> guiding_core::HemisphereGrid {
    support::hemisphere_grid(HemisphereMapping::ConcentricSquare, rule)
}

guide_properties!(hemisphere_cylindrical, guiding_core::HemisphereGrid, cylindrical);
guide_properties!(hemisphere_concentric, guiding_core::HemisphereGrid, concentric);
table_rule_properties!(hemisphere_cylindrical_rules, guiding_core::HemisphereGrid, cylindrical);
table_rule_properties!(hemisphere_concentric_rules, guiding_core::HemisphereGrid, concentric);
guide_properties!(irradiance_volume, guiding_core::IrradianceVolume, support::irradiance_volume);
table_rule_properties!(irradiance_volume_rules, guiding_core::IrradianceVolume, support::irradiance_volume);
// The mixture learns in batches (applied between passes): its rate checks live beside it
// in guiding-core (mixture::guide tests).
guide_properties!(gaussian_mixture, guiding_core::GaussianMixture, support::gaussian_mixture);
// The tree learns from records applied between passes: its rate and density checks live
// beside it in guiding-core (tree::guide tests).
guide_properties!(spatial_directional_tree, guiding_core::SpatialDirectionalTree, support::spatial_directional_tree);
