//! The focal guide's tests, and the helpers other focal modules' tests share.

use super::*;
use crate::distribution::DirectionalDistribution;
use crate::frame::Frame;
use crate::low_discrepancy::Pcg32;
use crate::validation::{chi_square_test, integrate_rectangle, ChiSquareSettings};
use glam::Vec2;

/// A guide that learned segments from all over the cube's −x side that all pass
/// through a small opening around `gap`.
fn learned_through(gap: Vec3) -> FocalGuide {
    // Coarser than the defaults, so that the quadrature of the pdf (which must find
    // every box between its grid points) stays quick.
    let settings = FocalGuideSettings { split_share: 1.0 / 512.0, max_boxes: 32, ..Default::default() };
    let mut guide = FocalGuide::new(Vec3::splat(-1.0), Vec3::splat(1.0), settings).unwrap();
    let mut rng = Pcg32::new(7, 1);
    for _ in 0..6 {
        for _ in 0..20_000 {
            let origin = Vec3::new(-0.95, 1.8 * rng.next_f32() - 0.9, 1.8 * rng.next_f32() - 0.9);
            let through = gap + 0.02 * (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5);
            let direction = (through - origin).normalize();
            let record = FocalRecord { origin, direction, length: f32::INFINITY, weight: 1.0 };
            assert_eq!(guide.record(&record, rng.next_f32()), UpdateOutcome::Accepted);
        }
        guide.rebuild_sampling();
    }
    guide
}

/// ∫ pdf dω over the sphere, adaptively to the given absolute error per leaf: the
/// pdf varies smoothly inside each box's cone (as t³), so splitting to full depth
/// wherever it is not constant (as [`pdf_integral`] does) would never end.
pub(in crate::focal) fn pdf_integral_within(pdf: &impl Fn(Vec3) -> f32, axis: Vec3, tolerance: f64) -> f64 {
    let frame = Frame::from_normal(axis);
    let (nz, nphi) = (32, 64);
    let mut total = 0.0;
    for i in 0..nz {
        let z = (-1.0 + 2.0 * i as f64 / nz as f64, -1.0 + 2.0 * (i + 1) as f64 / nz as f64);
        for j in 0..nphi {
            let tau = 2.0 * core::f64::consts::PI;
            let phi = (tau * j as f64 / nphi as f64, tau * (j + 1) as f64 / nphi as f64);
            total += integrate_rectangle(pdf, &frame, z, phi, tolerance, 14);
        }
    }
    total
}

/// The guide seen from one point, as a directional distribution for the shared
/// checks: the two extra uniforms come from a generator seeded by the two given.
pub(in crate::focal) struct FromPoint<'a> {
    pub(in crate::focal) guide: &'a FocalGuide,
    pub(in crate::focal) point: Vec3,
}

impl DirectionalDistribution for FromPoint<'_> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let mut rng = Pcg32::new(((u.x.to_bits() as u64) << 32) | u.y.to_bits() as u64, 3);
        let u3 = Vec3::new(u.y, rng.next_f32(), rng.next_f32());
        self.guide.sample(self.point, u.x, u3).unwrap_or(DirectionSample { direction: Vec3::NAN, pdf: 0.0 })
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        self.guide.pdf(self.point, direction)
    }
}

#[test]
fn boxes_gather_at_the_opening_and_sample_by_their_exact_pdf() {
    let gap = Vec3::new(0.3, 0.1, -0.2);
    let guide = learned_through(gap);
    assert!(!guide.boxes().is_empty());
    let near = guide.boxes().iter().all(|b| (0.5 * (b.low + b.high) - gap).length() < 0.25);
    assert!(near, "{:?}", guide.boxes());
    let largest = guide.boxes().iter().map(|b| (b.high - b.low).x).fold(0.0, f32::max);
    assert!(largest < 0.2, "the opening's leaves refined: {largest}");
    // From outside the boxes, and from inside one, the pdf integrates to one and the
    // sampler follows it.
    let inside = 0.5 * (guide.boxes()[0].low + guide.boxes()[0].high);
    for point in [Vec3::new(-0.9, 0.4, 0.5), inside] {
        let pdf = |d: Vec3| guide.pdf(point, d);
        let integral = pdf_integral_within(&pdf, (gap - point).normalize_or(Vec3::Z), 1e-6);
        assert!((integral - 1.0).abs() < 2e-3, "∫ pdf = {integral} from {point}");
        let from = FromPoint { guide: &guide, point };
        let settings = ChiSquareSettings { samples: 200_000, ..Default::default() };
        let report = chi_square_test(&from, (gap - point).normalize_or(Vec3::Z), &settings);
        assert!(report.p_value > 1e-3 && report.inconsistent_samples == 0, "{report:?} from {point}");
    }
}

#[test]
fn bad_records_and_arrivals_are_refused_and_teach_nothing() {
    let mut guide = FocalGuide::new(Vec3::ZERO, Vec3::ONE, FocalGuideSettings::default()).unwrap();
    let good = FocalRecord { origin: Vec3::splat(0.5), direction: Vec3::X, length: 0.3, weight: 1.0 };
    let cases = [
        (FocalRecord { weight: f32::NAN, ..good }, UpdateOutcome::RejectedNonFinite),
        (FocalRecord { weight: -1.0, ..good }, UpdateOutcome::RejectedNegative),
        (FocalRecord { direction: Vec3::splat(2.0), ..good }, UpdateOutcome::OutsideDomain),
        (FocalRecord { origin: Vec3::NAN, ..good }, UpdateOutcome::OutsideDomain),
        (FocalRecord { length: f32::NAN, ..good }, UpdateOutcome::OutsideDomain),
        (FocalRecord { origin: Vec3::splat(5.0), ..good }, UpdateOutcome::OutsideDomain),
    ];
    for (record, outcome) in cases {
        assert_eq!(guide.record(&record, 0.5), outcome, "{record:?}");
    }
    let arrival = FocalArrival {
        point: Vec3::splat(0.5),
        direction: Vec3::X,
        integrand: 1.0,
        pdf: 1.0,
        focal_pdf: 0.0,
        bsdf_pdf: 1.0,
        selection: 0.0,
    };
    assert_eq!(
        guide.record_arrival(&FocalArrival { integrand: f32::INFINITY, ..arrival }),
        UpdateOutcome::RejectedNonFinite
    );
    assert_eq!(guide.record_arrival(&FocalArrival { pdf: f32::NAN, ..arrival }), UpdateOutcome::OutsideDomain);
    guide.rebuild_sampling();
    assert!(guide.boxes().is_empty());
    assert_eq!(guide.sample(Vec3::splat(0.5), 0.5, Vec3::splat(0.5)), None);
    assert_eq!(guide.pdf(Vec3::splat(0.5), Vec3::X), 0.0);
    assert!(FocalGuide::new(Vec3::ONE, Vec3::ZERO, FocalGuideSettings::default()).is_err());
    let settings = FocalGuideSettings { split_share: 1.5, ..Default::default() };
    assert!(FocalGuide::new(Vec3::ZERO, Vec3::ONE, settings).is_err());
}

#[test]
fn each_cell_aims_as_often_as_its_arrivals_say_pays() {
    let mut guide = FocalGuide::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0), FocalGuideSettings::default()).unwrap();
    let (gap_side, open_side) = (Vec3::new(0.1, 0.5, 0.5), Vec3::new(1.9, 0.5, 0.5));
    let mut rng = Pcg32::new(3, 5);
    for _ in 0..4000 {
        // Drawn from the BSDF alone (selection 0), a direction is in the boxes' cone
        // one time in fifty. Where all the light comes through that cone, aiming pays;
        // where it arrives evenly, the BSDF alone is best.
        let in_cone = rng.next_f32() < 0.02;
        let (focal_pdf, bsdf_pdf) = if in_cone { (40.0, 0.3) } else { (0.0, 0.3) };
        let base = FocalArrival {
            point: gap_side,
            direction: Vec3::X,
            integrand: 0.0,
            pdf: bsdf_pdf,
            focal_pdf,
            bsdf_pdf,
            selection: 0.0,
        };
        let through_gap = if in_cone { 10.0 } else { 0.0 };
        guide.record_arrival(&FocalArrival { integrand: through_gap, ..base });
        guide.record_arrival(&FocalArrival { point: open_side, integrand: 0.3, ..base });
    }
    guide.rebuild_sampling();
    assert!(guide.selection_probability(gap_side) >= 0.35, "{}", guide.selection_probability(gap_side));
    assert_eq!(guide.selection_probability(open_side), 0.0);
}
