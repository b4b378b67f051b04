//! [`BoxCells`]: the focal boxes' probabilities learned per cell of the selection grid.
//!
//! From behind a wall, half of the boxes beyond a door's gap may be out of sight: a
//! direction aimed at them ends on the wall. Each cell learns which boxes its vertices'
//! light actually came through: every arrival adds its integrand / pdf to the boxes its
//! direction crosses, each by its share of the focal density along the direction (the
//! responsibilities of a mixture's EM step). At a refit each cell's boxes are drawn by
//! what it learned, mixed with the global masses so that no box it never tried is lost.

use alloc::vec;
use alloc::vec::Vec;
use core::sync::atomic::{AtomicU32, Ordering};

use glam::Vec3;

use super::guide::FocalBox;
use crate::atomic_f32;
use crate::cdf::{build_cdf, cdf_probability};

/// Share of a learned cell's box probabilities that stays with the global masses.
pub(super) const PRIOR_SHARE: f32 = 0.25;

/// Arrivals a cell needs in an epoch before it learns its own box probabilities.
pub(super) const MIN_ARRIVALS: u32 = 64;

/// Most cells × boxes held: beyond it the boxes are drawn by their global masses alone.
pub(super) const MAX_ENTRIES: usize = 1 << 20;

/// Per cell and box: what the epoch's arrivals found through the box, and the scale of
/// the box's global probability that the cell samples with.
#[derive(Debug, Default)]
pub(super) struct BoxCells {
    cells: usize,
    /// Entries per cell: the boxes, padded to whole lanes.
    stride: usize,
    /// Per cell × box: Σ integrand / pdf × the box's share of the focal density (f32 bits).
    found: Vec<AtomicU32>,
    /// Per cell: the epoch's arrivals.
    arrivals: Vec<AtomicU32>,
    /// Per cell × box: the cell's probability of the box ÷ its global probability; empty
    /// where no cell learned its own.
    scale: Vec<f32>,
    /// Per cell × box: the cell's cumulative probabilities (the last 1); a cell that has
    /// not learned its own has all of them 0 and draws by the global ones.
    cdf: Vec<f32>,
}

impl BoxCells {
    /// Room for `cells` cells of `stride` boxes (none where that passes [`MAX_ENTRIES`]).
    pub(super) fn new(cells: usize, stride: usize) -> Self {
        let entries = cells.saturating_mul(stride);
        if entries == 0 || entries > MAX_ENTRIES {
            return Self::default();
        }
        Self {
            cells,
            stride,
            found: (0..entries).map(|_| atomic_f32::new(0.0)).collect(),
            arrivals: (0..cells).map(|_| AtomicU32::new(0)).collect(),
            scale: Vec::new(),
            cdf: Vec::new(),
        }
    }

    /// Whether it learns at all.
    pub(super) fn enabled(&self) -> bool {
        self.cells > 0
    }

    /// Bytes held.
    pub(super) fn memory_bytes(&self) -> usize {
        4 * (self.found.len() + self.arrivals.len() + self.scale.len() + self.cdf.len())
    }

    /// The scales of `cell`'s boxes (one per box, lanes padded), if it learned its own.
    #[inline]
    pub(super) fn scales(&self, cell: usize) -> Option<&[f32]> {
        let entries = self.scale.get(cell * self.stride..(cell + 1) * self.stride)?;
        let learned = self.cdf.get((cell + 1) * self.stride - 1).is_some_and(|&last| last > 0.0);
        learned.then_some(entries)
    }

    /// `cell`'s cumulative box probabilities, if it learned its own.
    #[inline]
    pub(super) fn cdf(&self, cell: usize) -> Option<&[f32]> {
        self.scales(cell)?;
        self.cdf.get(cell * self.stride..(cell + 1) * self.stride)
    }

    /// Counts one arrival in `cell`.
    #[inline]
    pub(super) fn count(&self, cell: usize) {
        if let Some(count) = self.arrivals.get(cell) {
            atomic_f32::increment_saturating(count);
        }
    }

    /// Adds `amount` to what `cell` found through box `index`.
    #[inline]
    pub(super) fn add(&self, cell: usize, index: usize, amount: f32) {
        if let Some(sum) = self.found.get(cell * self.stride + index) {
            atomic_f32::update(sum, |s| (s + amount).min(f32::MAX));
        }
    }

    /// Each cell's box multipliers for the epoch that ends, relative to the global box
    /// probabilities `global` it was sampled with: what it found through each box over
    /// all it found, ÷ the box's global probability, where it had enough arrivals; its
    /// scales so far elsewhere (none: `None`).
    pub(super) fn multipliers(&self, global: &[f32]) -> Vec<Option<Vec<f32>>> {
        (0..self.cells)
            .map(|cell| {
                let found: Vec<f32> =
                    (0..global.len()).map(|k| atomic_f32::load(&self.found[cell * self.stride + k])).collect();
                let total: f64 = found.iter().map(|&f| f as f64).sum();
                let enough = self.arrivals[cell].load(Ordering::Relaxed) >= MIN_ARRIVALS;
                if enough && total > 0.0 && total.is_finite() {
                    let m = found
                        .iter()
                        .zip(global)
                        .map(|(&f, &p)| if p > 0.0 { (f as f64 / total) as f32 / p } else { 0.0 });
                    Some(m.collect())
                } else {
                    self.scales(cell).map(|s| s[..global.len()].to_vec())
                }
            })
            .collect()
    }

    /// Starts an epoch over boxes of global probabilities `global` (padded to `stride`
    /// entries a cell), each cell drawing box k with
    /// (1 − [`PRIOR_SHARE`]) · p_k·m_k / Σ p·m + [`PRIOR_SHARE`] · p_k for the multipliers
    /// `multipliers` (by the global masses alone where it has none).
    pub(super) fn restart(&mut self, cells: usize, stride: usize, global: &[f32], multipliers: &[Option<Vec<f32>>]) {
        *self = Self::new(cells, stride);
        if !self.enabled() || multipliers.iter().all(Option::is_none) {
            return;
        }
        self.scale = vec![1.0; cells * stride];
        self.cdf = vec![0.0; cells * stride];
        for (cell, m) in multipliers.iter().enumerate().take(cells) {
            let Some(m) = m else { continue };
            let weighted: f64 = global.iter().zip(m).map(|(&p, &m)| p as f64 * m as f64).sum();
            if !(weighted > 0.0 && weighted.is_finite()) {
                continue;
            }
            // The padding lanes weigh nothing: never drawn, their scale 0.
            let probability = |k: usize| match (global.get(k), m.get(k)) {
                (Some(&p), Some(&m)) => {
                    let learned = p as f64 * m as f64 / weighted;
                    ((1.0 - PRIOR_SHARE as f64) * learned + PRIOR_SHARE as f64 * p as f64) as f32
                }
                _ => 0.0,
            };
            let cdf = &mut self.cdf[cell * stride..(cell + 1) * stride];
            build_cdf(cdf, 0.0, probability);
            // The scale is what the cdf draws over what the global one does, so the pdf
            // matches the sampler to the last quantum.
            for (k, scale) in self.scale[cell * stride..(cell + 1) * stride].iter_mut().enumerate() {
                let p = global.get(k).copied().unwrap_or(0.0);
                *scale = if p > 0.0 { cdf_probability(cdf, k) / p } else { 0.0 };
            }
        }
    }
}

/// The probabilities of a cumulative distribution's entries.
pub(super) fn probabilities(cdf: &[f32]) -> Vec<f32> {
    (0..cdf.len()).map(|k| cdf_probability(cdf, k)).collect()
}

/// The multiplier a new box at `center` takes from the old boxes' `multipliers`: that of
/// the old box holding its centre (1 where none does: a new box is sampled by its mass).
pub(super) fn carry_multiplier(old: &[FocalBox], multipliers: &[f32], center: Vec3) -> f32 {
    old.iter()
        .zip(multipliers)
        .find(|(b, _)| center.cmpge(b.low).all() && center.cmple(b.high).all())
        .map_or(1.0, |(_, &m)| m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::focal::guide::tests::{pdf_integral_within, FromPoint};
    use crate::focal::{FocalArrival, FocalGuide, FocalGuideSettings, FocalRecord};
    use crate::low_discrepancy::Pcg32;
    use crate::validation::{chi_square_test, ChiSquareSettings};

    #[test]
    fn a_cell_learns_the_boxes_its_light_came_through_and_keeps_a_prior() {
        let global = [0.5f32, 0.25, 0.25];
        let mut cells = BoxCells::new(2, 8);
        assert!(cells.enabled());
        for _ in 0..MIN_ARRIVALS {
            cells.count(0);
            cells.add(0, 1, 1.0);
        }
        cells.count(1);
        cells.add(1, 0, 1.0);
        let m = cells.multipliers(&global);
        assert_eq!(m[0].as_deref(), Some(&[0.0, 4.0, 0.0][..]), "all of cell 0's light came through box 1");
        assert!(m[1].is_none(), "cell 1 had too few arrivals");
        cells.restart(2, 8, &global, &m);
        let cdf = cells.cdf(0).unwrap();
        // Box 1: 0.75 learned + 0.25 × 0.25 of the prior.
        let expected = [0.125f32, 0.125 + 0.8125, 1.0];
        assert!(cdf[..3].iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-6), "{cdf:?}");
        assert_eq!(cells.scales(0).unwrap()[..3], [0.25, 3.25, 0.25]);
        assert!(cells.cdf(1).is_none() && cells.scales(1).is_none());
        // A cell that learns nothing next epoch keeps its scales.
        let kept = cells.multipliers(&global);
        assert_eq!(kept[0].as_deref(), Some(&[0.25, 3.25, 0.25][..]));
        assert!(!BoxCells::new(MAX_ENTRIES, 2).enabled(), "too many entries");
    }

    /// Two openings in a wall; a cell on one side sees its light come through one of
    /// them only. Learning boxes per cell, it aims at that opening's boxes far more often
    /// than their mass alone says, and its pdf still integrates to one and matches its
    /// sampler.
    #[test]
    fn a_cell_learns_which_boxes_its_light_comes_through() {
        let settings =
            FocalGuideSettings { split_share: 1.0 / 512.0, max_boxes: 32, boxes_per_cell: true, ..Default::default() };
        let mut guide = FocalGuide::new(Vec3::splat(-1.0), Vec3::splat(1.0), settings).unwrap();
        let (left, right) = (Vec3::new(0.0, 0.5, -0.5), Vec3::new(0.0, 0.5, 0.5));
        let viewer = Vec3::new(-0.9, -0.9, -0.9);
        let mut rng = Pcg32::new(9, 2);
        for _ in 0..6 {
            for i in 0..20_000 {
                // Both openings carry the same light from all over the −x side.
                let origin = Vec3::new(-0.95, 1.8 * rng.next_f32() - 0.9, 1.8 * rng.next_f32() - 0.9);
                let gap = if i % 2 == 0 { left } else { right };
                let through = gap + 0.02 * (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5);
                let direction = (through - origin).normalize();
                let record = FocalRecord { origin, direction, length: f32::INFINITY, weight: 1.0 };
                guide.record(&record, rng.next_f32());
                // The viewer's directions drawn by the guide: only those towards the left
                // opening bring light.
                if let Some(s) =
                    guide.sample(viewer, rng.next_f32(), Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
                {
                    let towards_left = (s.direction - (left - viewer).normalize()).length() < 0.1;
                    let integrand = if towards_left { 1.0 } else { 0.0 };
                    let arrival = FocalArrival {
                        point: viewer,
                        direction: s.direction,
                        integrand,
                        pdf: s.pdf,
                        focal_pdf: s.pdf,
                        bsdf_pdf: 0.0,
                        selection: 1.0,
                    };
                    guide.record_arrival(&arrival);
                }
            }
            guide.rebuild_sampling();
        }
        let (mut towards_left, n) = (0, 20_000);
        for _ in 0..n {
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let s = guide.sample(viewer, rng.next_f32(), u).unwrap();
            towards_left += ((s.direction - (left - viewer).normalize()).length() < 0.1) as u32;
        }
        // By mass alone, half; learned, the 3/4 learned share plus the prior's half of 1/4.
        assert!(towards_left as f32 > 0.8 * n as f32, "{towards_left} of {n} towards the left opening");
        let pdf = |d: Vec3| guide.pdf(viewer, d);
        let integral = pdf_integral_within(&pdf, (left - viewer).normalize(), 1e-6);
        assert!((integral - 1.0).abs() < 2e-3, "∫ pdf = {integral}");
        let from = FromPoint { guide: &guide, point: viewer };
        let settings = ChiSquareSettings { samples: 200_000, ..Default::default() };
        let report = chi_square_test(&from, (left - viewer).normalize(), &settings);
        assert!(report.p_value > 1e-3 && report.inconsistent_samples == 0, "{report:?}");
    }
}
