//! Boxes the focal guide is told about before it learns anything: places light is known
//! to seem to come from, such as a light's mirror image behind a flat mirror or a
//! polished floor. Segments that reach a light by way of the mirror end at the mirror,
//! so the octree never gathers mass at the image; yet from every vertex that sees the
//! reflection, the image is one fixed spot to aim at (the focal points Rath et al. 2023
//! find behind mirrors). They join the learned boxes at every rebuild with a share of
//! the mass, and each selection cell learns, as for any box, whether aiming there pays.

use alloc::vec::Vec;

use glam::Vec3;

use super::merge::MassBox;
use crate::error::Error;

/// Most known boxes a guide takes.
pub const MAX_KNOWN_BOXES: usize = 64;

/// A box a caller knows light seems to come from, with its weight among such boxes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownBox {
    /// Lower corner, world space, metres.
    pub low: Vec3,
    /// Upper corner (≥ `low` on every axis; a flat box is thickened).
    pub high: Vec3,
    /// Its weight among the known boxes (> 0; e.g. the power it seems to emit, W).
    pub weight: f32,
}

/// The known boxes with their share of the mass.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct KnownBoxes {
    boxes: Vec<KnownBox>,
    /// Their mass together, as a share of the learned boxes' mass.
    share: f32,
}

impl KnownBoxes {
    /// Checks `boxes` (finite corners, high ≥ low, positive finite weights, at most
    /// [`MAX_KNOWN_BOXES`]) and `share` (finite, > 0), thickening flat boxes to a
    /// thousandth of their largest side (a box needs a volume to hold a density).
    pub(super) fn new(boxes: &[KnownBox], share: f32) -> Result<Self, Error> {
        let invalid = |name, value: f64, requirement| Err(Error::InvalidSetting { name, value, requirement });
        if !(share.is_finite() && share > 0.0) {
            return invalid("known_box_share", share as f64, "finite and above 0");
        }
        if boxes.len() > MAX_KNOWN_BOXES {
            return invalid("known_boxes", boxes.len() as f64, "at most 64 boxes");
        }
        let mut thickened = Vec::with_capacity(boxes.len());
        for b in boxes {
            if !(b.low.is_finite() && b.high.is_finite() && b.high.cmpge(b.low).all()) {
                return invalid("known_boxes", f64::NAN, "finite corners with high ≥ low on every axis");
            }
            if !(b.weight.is_finite() && b.weight > 0.0) {
                return invalid("known_boxes", b.weight as f64, "weights finite and above 0");
            }
            let size = b.high - b.low;
            let least = (1e-3 * size.max_element()).max(1e-6 * b.low.abs().max(b.high.abs()).max_element()).max(1e-9);
            let grow = (Vec3::splat(least) - size).max(Vec3::ZERO) * 0.5;
            thickened.push(KnownBox { low: b.low - grow, high: b.high + grow, weight: b.weight });
        }
        Ok(Self { boxes: thickened, share })
    }

    /// Whether there are none.
    pub(super) fn is_empty(&self) -> bool {
        self.boxes.is_empty()
    }

    /// Appends the boxes to `chosen` (the learned boxes), with `share` of their mass
    /// split by weight; `fallback` is the mass they share when nothing was chosen.
    pub(super) fn add_to(&self, chosen: &mut Vec<MassBox>, fallback: f64) {
        let learned: f64 = chosen.iter().map(|b| b.mass).sum();
        let mass = if learned > 0.0 { self.share as f64 * learned } else { fallback };
        let total: f64 = self.boxes.iter().map(|b| b.weight as f64).sum();
        if !(mass > 0.0 && mass.is_finite() && total > 0.0) {
            return;
        }
        chosen.extend(self.boxes.iter().map(|b| MassBox {
            low: b.low,
            high: b.high,
            mass: mass * b.weight as f64 / total,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::focal::guide::tests::{pdf_integral_within, FromPoint};
    use crate::focal::{FocalGuide, FocalGuideSettings, FocalRecord};
    use crate::validation::{chi_square_test, ChiSquareSettings};

    /// A light's mirror image below a floor (z = 0) is a box no segment reaches: told of
    /// it, the guide aims there beside what it learned, by the exact pdf.
    #[test]
    fn a_known_box_is_sampled_beside_the_learned_ones_by_its_exact_pdf() {
        let settings = FocalGuideSettings { split_share: 1.0 / 64.0, max_boxes: 8, ..Default::default() };
        let mut guide = FocalGuide::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
        let image = KnownBox { low: Vec3::new(0.2, 0.2, -0.6), high: Vec3::new(0.5, 0.3, -0.6), weight: 2.0 };
        assert!(guide.set_known_boxes(&[KnownBox { weight: -1.0, ..image }], 0.5).is_err());
        assert!(!guide.has_known_boxes(), "a refused box changes nothing");
        guide.set_known_boxes(&[image], 0.5).unwrap();
        assert!(guide.has_known_boxes());
        // One learned spot, in the upper half.
        let gap = Vec3::new(-0.4, 0.1, 0.6);
        for _ in 0..3 {
            for k in 0..4000 {
                let origin = Vec3::new(-0.9, -0.9 + 1.8 * (k % 64) as f32 / 64.0, 0.9 - 1.8 * (k / 64) as f32 / 64.0);
                let record = FocalRecord { origin, direction: (gap - origin).normalize(), length: 9.0, weight: 1.0 };
                guide.record(&record, 0.5);
            }
            guide.rebuild_sampling();
        }
        let boxes = guide.boxes();
        let known = boxes.iter().filter(|b| b.low.z < -0.5).count();
        assert_eq!(known, 1, "{boxes:?}");
        assert!(boxes.len() > 1, "the learned boxes stay: {boxes:?}");
        let point = Vec3::new(0.9, -0.5, 0.4);
        let towards = (Vec3::new(0.35, 0.25, -0.6) - point).normalize();
        assert!(guide.pdf(point, towards) > 0.0);
        let pdf = |d: Vec3| guide.pdf(point, d);
        let integral = pdf_integral_within(&pdf, towards, 1e-6);
        assert!((integral - 1.0).abs() < 2e-3, "∫ pdf = {integral}");
        let settings = ChiSquareSettings { samples: 200_000, ..Default::default() };
        let report = chi_square_test(&FromPoint { guide: &guide, point }, towards, &settings);
        assert!(report.p_value > 1e-3 && report.inconsistent_samples == 0, "{report:?}");
        guide.set_known_boxes(&[], 0.5).unwrap();
        guide.rebuild_sampling();
        assert!(guide.boxes().iter().all(|b| b.low.z > -0.5), "removed");
    }

    #[test]
    fn flat_boxes_are_thickened_and_bad_ones_refused() {
        let flat = KnownBox { low: Vec3::new(0.0, 0.0, 2.0), high: Vec3::new(1.0, 2.0, 2.0), weight: 1.0 };
        let known = KnownBoxes::new(&[flat], 0.5).unwrap();
        let b = known.boxes[0];
        assert!((b.high.z - b.low.z - 2e-3).abs() < 1e-6, "{b:?}");
        assert_eq!((b.low.x, b.high.y), (0.0, 2.0));
        let bad = [
            KnownBox { weight: 0.0, ..flat },
            KnownBox { weight: f32::NAN, ..flat },
            KnownBox { low: Vec3::splat(f32::INFINITY), ..flat },
            KnownBox { high: Vec3::ZERO, ..flat },
        ];
        for b in bad {
            assert!(KnownBoxes::new(&[b], 0.5).is_err(), "{b:?}");
        }
        assert!(KnownBoxes::new(&[flat], 0.0).is_err());
        assert!(KnownBoxes::new(&[flat; MAX_KNOWN_BOXES + 1], 0.5).is_err());
    }

    #[test]
    fn the_share_is_split_by_weight() {
        let a = KnownBox { low: Vec3::ZERO, high: Vec3::ONE, weight: 3.0 };
        let b = KnownBox { weight: 1.0, ..a };
        let known = KnownBoxes::new(&[a, b], 0.5).unwrap();
        let mut chosen = alloc::vec![MassBox { low: Vec3::ZERO, high: Vec3::ONE, mass: 8.0 }];
        known.add_to(&mut chosen, 1.0);
        let masses: Vec<f64> = chosen.iter().map(|b| b.mass).collect();
        assert_eq!(masses, [8.0, 3.0, 1.0]);
        let mut none = Vec::new();
        known.add_to(&mut none, 2.0);
        assert_eq!(none.iter().map(|b| b.mass).sum::<f64>(), 2.0, "alone they share the fallback");
    }
}
