//! [`LightGuide`]: per grid cell, a learned importance V per light and a selection CDF.

use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

use alloc::vec;
use alloc::vec::Vec;
use glam::Vec3;

use crate::atomic_f32;
use crate::average_records::Learned;
use crate::cdf::{build_cdf, cdf_probability, sample_cdf};
use crate::cell_grid::CellGrid;
use crate::error::Error;
use crate::update_rule::{classify_target, UpdateOutcome};

use super::settings::{LightGuideSettings, LightUpdateRule, ENTRY_BYTES, MAX_LIGHTS};

/// A cell of a [`LightGuide`]'s grid: the region [`LightGuide::locate`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LightCell(pub u32);

/// A selected light and the probability it had (exactly what
/// [`LightGuide::probability`] reports for it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightChoice {
    /// Index of the light, in the order of the powers the guide was built with.
    pub light: u32,
    /// Its selection probability in the cell, > 0.
    pub probability: f32,
}

/// Learned light selection for next-event estimation: a regular grid over the scene,
/// and in each cell c a value V(c, l) per light l learned from shadow rays (Eq. 3 of
/// Dahm & Keller), mixed with power-proportional and uniform shares.
///
/// ```
/// use guiding_core::{LightGuide, LightGuideSettings};
/// use glam::Vec3;
///
/// // Two equal lights; from this corner of the scene only light 1 is ever visible.
/// let mut guide = LightGuide::new(Vec3::ZERO, Vec3::ONE, &[1.0, 1.0], LightGuideSettings::default())?;
/// let cell = guide.locate(Vec3::splat(0.1)).expect("inside the bounds");
/// for _ in 0..100 {
///     guide.update(cell, 0, 0.0, false);
///     guide.update(cell, 1, 2.0, true);
/// }
/// guide.rebuild_sampling();
/// assert!(guide.probability(cell, 1) > 0.85);
/// assert!(guide.probability(cell, 0) > 0.0); // never zero
/// let choice = guide.select(cell, 0.5);
/// assert_eq!(choice.probability, guide.probability(cell, choice.light));
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Debug)]
pub struct LightGuide {
    pub(super) settings: LightGuideSettings,
    /// The box it was built over (scene units).
    pub(super) bounds: (Vec3, Vec3),
    grid: CellGrid,
    pub(super) lights: usize,
    /// Normalised power of each light.
    pub(super) power_share: Vec<f32>,
    /// Per (cell, light): V (f32 bits), updates taken, shadow rays shot.
    pub(super) values: Vec<AtomicU32>,
    pub(super) updates: Vec<AtomicU32>,
    pub(super) shots: Vec<AtomicU32>,
    /// Per (cell, light): the selection CDF of the last rebuild.
    cdf: Vec<f32>,
    pub(super) rejected: AtomicUsize,
}

impl LightGuide {
    /// A guide over the box `low..high` (scene units) for lights of the given powers
    /// (any consistent unit, e.g. luminance × area; all zero means equal).
    pub fn new(low: Vec3, high: Vec3, powers: &[f32], settings: LightGuideSettings) -> Result<Self, Error> {
        settings.validate()?;
        let invalid = |name, value: f64, requirement| Err(Error::InvalidSetting { name, value, requirement });
        if powers.is_empty() || powers.len() > MAX_LIGHTS {
            return invalid("light_count", powers.len() as f64, "in 1..=2^20");
        }
        if let Some(&p) = powers.iter().find(|p| !(p.is_finite() && **p >= 0.0)) {
            return invalid("light_powers", p as f64, "finite and non-negative");
        }
        let lights = powers.len();
        let bytes_per_cell = lights * ENTRY_BYTES;
        let grid = CellGrid::new(low, high, settings.resolution, settings.budget_bytes, bytes_per_cell)?;
        let cells = grid.cell_count();
        let entries = cells * lights;
        let total: f64 = powers.iter().map(|&p| p as f64).sum();
        let power_share =
            powers.iter().map(|&p| if total > 0.0 { (p as f64 / total) as f32 } else { 1.0 / lights as f32 }).collect();
        let mut guide = Self {
            settings,
            bounds: (low, high),
            grid,
            lights,
            power_share,
            values: (0..entries).map(|_| atomic_f32::new(0.0)).collect(),
            updates: (0..entries).map(|_| AtomicU32::new(0)).collect(),
            shots: (0..entries).map(|_| AtomicU32::new(0)).collect(),
            cdf: vec![0.0; entries],
            rejected: AtomicUsize::new(0),
        };
        guide.rebuild_sampling();
        Ok(guide)
    }

    /// The cell holding `position`; points outside the bounds use the nearest cell.
    /// `None` for a non-finite position.
    pub fn locate(&self, position: Vec3) -> Option<LightCell> {
        self.grid.cell(position).map(LightCell)
    }

    /// The table index of (`cell`, `light`), or `None` where either is out of range.
    #[inline]
    pub(super) fn entry(&self, cell: LightCell, light: u32) -> Option<usize> {
        let in_range = (light as usize) < self.lights && (cell.0 as usize) < self.cell_count();
        in_range.then(|| cell.0 as usize * self.lights + light as usize)
    }

    /// Entries in the tables: cells × lights.
    #[inline]
    pub(super) fn entry_count(&self) -> usize {
        self.shots.len()
    }

    fn row(&self, cell: LightCell) -> core::ops::Range<usize> {
        let start = cell.0 as usize * self.lights;
        start..start + self.lights
    }

    /// Picks a light by the cell's CDF from a uniform number in [0, 1).
    pub fn select(&self, cell: LightCell, u: f32) -> LightChoice {
        let cdf = &self.cdf[self.row(cell)];
        let (light, _) = sample_cdf(cdf, u);
        LightChoice { light: light as u32, probability: cdf_probability(cdf, light) }
    }

    /// The probability with which [`select`](Self::select) picks `light` in `cell`.
    pub fn probability(&self, cell: LightCell, light: u32) -> f32 {
        if light as usize >= self.lights {
            return 0.0;
        }
        cdf_probability(&self.cdf[self.row(cell)], light as usize)
    }

    /// Learns from one shadow ray from `cell` to `light`: `unoccluded` says whether it
    /// arrived, `contribution` is ‖C‖∞ of the unshadowed contribution (radiance, the
    /// light's whole area: divide by the pdf of the point chosen on it). NaN, infinite
    /// and negative contributions are rejected and counted. Where many threads learn at
    /// once, [`record`](Self::record) into each thread's [`LightRecords`](super::LightRecords)
    /// and [`splat`](Self::splat) them between passes instead: no locked writes on shared
    /// lines.
    pub fn update(&self, cell: LightCell, light: u32, contribution: f32, unoccluded: bool) -> UpdateOutcome {
        let Some(index) = self.entry(cell, light) else { return UpdateOutcome::OutsideDomain };
        let learned = match self.learned(contribution, unoccluded) {
            Ok(learned) => learned,
            Err(rejected) => return rejected,
        };
        atomic_f32::increment_saturating(&self.shots[index]);
        match learned {
            Learned::Target(target) => atomic_f32::running_average(&self.values[index], &self.updates[index], target),
            Learned::Count => {
                atomic_f32::increment_saturating(&self.updates[index]);
            }
            Learned::Nothing => {}
        }
        UpdateOutcome::Accepted
    }

    /// What one shadow ray teaches an entry under the guide's rule, shared by
    /// [`update`](Self::update) and [`record`](Self::record); a rejected contribution
    /// (NaN, infinite, negative) is counted and its outcome returned.
    #[inline]
    pub(super) fn learned(&self, contribution: f32, unoccluded: bool) -> Result<Learned, UpdateOutcome> {
        let contribution = classify_target(contribution).inspect_err(|_| {
            self.rejected.fetch_add(1, Ordering::Relaxed);
        })?;
        Ok(match (self.settings.rule, unoccluded) {
            (LightUpdateRule::UnoccludedAverage, true) => Learned::Target(contribution),
            (LightUpdateRule::MeanContribution, _) => Learned::Target(if unoccluded { contribution } else { 0.0 }),
            (LightUpdateRule::VisibilityRatio, true) => Learned::Count,
            _ => Learned::Nothing,
        })
    }

    /// Adds what `other` learned (another process or thread of the same scene, e.g. a
    /// render farm's node) to this guide and rebuilds: per (cell, light) the values are
    /// averaged by their update counts and the counts and shadow rays add, so the merge
    /// is exact (the guide one process would have learned from both sets of rays). Both
    /// must have the same bounds, lights and settings; otherwise nothing changes and
    /// [`Error::Incompatible`] names what differs.
    pub fn merge(&mut self, other: &LightGuide) -> Result<(), Error> {
        if self.settings != other.settings {
            return Err(Error::Incompatible { what: "settings" });
        }
        if self.bounds != other.bounds || self.grid.resolution() != other.grid.resolution() {
            return Err(Error::Incompatible { what: "bounds" });
        }
        if self.power_share != other.power_share {
            return Err(Error::Incompatible { what: "lights" });
        }
        if self.settings.rule == LightUpdateRule::VisibilityRatio {
            // Hits and shots are both counts.
            for (count, other_count) in self.updates.iter().zip(&other.updates) {
                count.store(
                    count.load(Ordering::Relaxed).saturating_add(other_count.load(Ordering::Relaxed)),
                    Ordering::Relaxed,
                );
            }
        } else {
            atomic_f32::merge_running_averages(&self.values, &self.updates, &other.values, &other.updates);
        }
        for (shots, other_shots) in self.shots.iter().zip(&other.shots) {
            shots.store(
                shots.load(Ordering::Relaxed).saturating_add(other_shots.load(Ordering::Relaxed)),
                Ordering::Relaxed,
            );
        }
        self.rejected.fetch_add(other.rejected.load(Ordering::Relaxed), Ordering::Relaxed);
        self.rebuild_sampling();
        Ok(())
    }

    /// Forgets everything learned: every value, update and shadow-ray count back to 0
    /// (selection by power and the uniform share alone, as [`new`](Self::new) made it).
    pub fn reset(&mut self) {
        for counter in self.values.iter().chain(&self.updates).chain(&self.shots) {
            counter.store(0, Ordering::Relaxed);
        }
        self.rejected.store(0, Ordering::Relaxed);
        self.rebuild_sampling();
    }

    /// Rebuilds every cell's selection CDF from what it learned: probability
    /// (1 - power_mix - uniform_mix)·V/ΣV + power_mix·power share + uniform_mix/lights
    /// (cells that learned nothing yet use power and uniform shares alone). Call between
    /// passes.
    pub fn rebuild_sampling(&mut self) {
        let (power_mix, uniform_mix) = (self.settings.power_mix as f64, self.settings.uniform_mix as f64);
        let mut learned = vec![0.0f64; self.lights];
        for cell in 0..self.cell_count() {
            let row = self.row(LightCell(cell as u32));
            for (l, value) in learned.iter_mut().enumerate() {
                let i = row.start + l;
                *value = match self.settings.rule {
                    LightUpdateRule::VisibilityRatio => {
                        let (hits, shots) =
                            (self.updates[i].load(Ordering::Relaxed), self.shots[i].load(Ordering::Relaxed));
                        (hits as f64 + 1.0) / (shots as f64 + 2.0) * self.power_share[l] as f64
                    }
                    _ => atomic_f32::load(&self.values[i]) as f64,
                };
            }
            let total: f64 = learned.iter().sum();
            let learned_mix = if total > 0.0 { 1.0 - power_mix - uniform_mix } else { 0.0 };
            let power_mix = 1.0 - uniform_mix - learned_mix;
            let weight = |l: usize| {
                let share = if total > 0.0 { learned[l] / total } else { 0.0 };
                (learned_mix * share + power_mix * self.power_share[l] as f64 + uniform_mix / self.lights as f64) as f32
            };
            build_cdf(&mut self.cdf[row], 0.0, weight);
        }
    }

    /// Cells along x, y and z.
    pub fn resolution(&self) -> [u32; 3] {
        self.grid.resolution()
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.grid.cell_count()
    }

    /// Number of lights.
    pub fn light_count(&self) -> usize {
        self.lights
    }

    /// Bytes held by the tables.
    pub fn memory_bytes(&self) -> usize {
        self.cell_count() * self.lights * ENTRY_BYTES + self.lights * 4 + core::mem::size_of::<Self>()
    }

    /// Contributions rejected for being NaN, infinite or negative.
    pub fn rejected_updates(&self) -> usize {
        self.rejected.load(Ordering::Relaxed)
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &LightGuideSettings {
        &self.settings
    }

    /// The guide as bytes (versioned, checksummed): what it learned, its settings and
    /// bounds; [`from_bytes`](Self::from_bytes) reads them back. Call between passes.
    pub fn to_bytes(&self) -> Vec<u8> {
        super::serialize::encode(self)
    }

    /// Reads a guide written by [`to_bytes`](Self::to_bytes), checking every field
    /// (damaged or foreign bytes give an error naming what is wrong, never a panic);
    /// its selection CDFs are rebuilt from what it learned.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        super::serialize::decode(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;
    use crate::validation::discrete_chi_square;

    fn guide(powers: &[f32], settings: LightGuideSettings) -> LightGuide {
        LightGuide::new(Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0), powers, settings).unwrap()
    }

    #[test]
    fn reset_gives_the_guide_made_fresh() {
        let fresh = guide(&[1.0, 3.0], LightGuideSettings::default());
        let mut learned = guide(&[1.0, 3.0], LightGuideSettings::default());
        let cell = learned.locate(Vec3::ONE).unwrap();
        for i in 0..50 {
            learned.update(cell, i % 2, 2.0, i % 3 != 0);
        }
        learned.update(cell, 0, f32::NAN, true);
        learned.rebuild_sampling();
        assert_ne!(learned.to_bytes(), fresh.to_bytes());
        learned.reset();
        assert_eq!(learned.to_bytes(), fresh.to_bytes());
        assert_eq!(learned.probability(cell, 1), fresh.probability(cell, 1));
    }

    #[test]
    fn merging_two_halves_learns_what_one_guide_learns_from_all() {
        for rule in
            [LightUpdateRule::MeanContribution, LightUpdateRule::UnoccludedAverage, LightUpdateRule::VisibilityRatio]
        {
            let settings = LightGuideSettings { rule, ..Default::default() };
            let powers = [1.0, 2.0, 5.0, 0.5];
            let (mut first, second, mut whole) =
                (guide(&powers, settings), guide(&powers, settings), guide(&powers, settings));
            let mut rng = Pcg32::new(8, 1);
            for i in 0..20_000 {
                let point = Vec3::new(4.0 * rng.next_f32(), 2.0 * rng.next_f32(), rng.next_f32());
                let cell = whole.locate(point).unwrap();
                let light = rng.next_u32() % 4;
                let (contribution, unoccluded) = (rng.next_f32() * (1 + light) as f32, rng.next_f32() < 0.6);
                whole.update(cell, light, contribution, unoccluded);
                let half = if i % 2 == 0 { &first } else { &second };
                half.update(cell, light, contribution, unoccluded);
            }
            whole.rebuild_sampling();
            first.merge(&second).unwrap();
            for cell in 0..whole.cell_count() as u32 {
                for light in 0..4 {
                    let (merged, all) =
                        (first.probability(LightCell(cell), light), whole.probability(LightCell(cell), light));
                    assert!(
                        (merged - all).abs() <= 1e-5 * all.max(1e-3),
                        "{rule:?} cell {cell} light {light}: {merged} vs {all}"
                    );
                }
            }
            let other = LightGuide::new(Vec3::ZERO, Vec3::ONE, &powers, settings).unwrap();
            assert!(matches!(first.merge(&other), Err(Error::Incompatible { what: "bounds" })));
            let brighter = guide(&[1.0, 2.0, 5.0, 9.0], settings);
            assert!(matches!(first.merge(&brighter), Err(Error::Incompatible { what: "lights" })));
        }
    }

    #[test]
    fn sampling_matches_the_probabilities_by_chi_square() {
        let powers: Vec<f32> = (0..40).map(|i| 1.0 + (i % 7) as f32 * 3.0).collect();
        let mut g = guide(&powers, LightGuideSettings::default());
        let cell = g.locate(Vec3::new(1.0, 1.0, 0.5)).unwrap();
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..10_000 {
            let light = rng.next_u32() % 40;
            g.update(cell, light, (light % 5) as f32 * rng.next_f32(), rng.next_f32() < 0.5);
        }
        g.rebuild_sampling();
        let probabilities: Vec<f64> = (0..40).map(|l| g.probability(cell, l) as f64).collect();
        assert!((probabilities.iter().sum::<f64>() - 1.0).abs() < 1e-6);
        let mut observed = vec![0u64; 40];
        for _ in 0..1_000_000 {
            let choice = g.select(cell, rng.next_f32());
            assert_eq!(choice.probability, g.probability(cell, choice.light));
            observed[choice.light as usize] += 1;
        }
        let report = discrete_chi_square(&probabilities, &observed, 5.0);
        assert!(report.passes(0.01), "{report:?}");
        // A deliberately wrong claim fails.
        let mut wrong = probabilities.clone();
        wrong.swap(0, 39);
        wrong.swap(1, 38);
        assert!(!discrete_chi_square(&wrong, &observed, 5.0).passes(0.01));
    }

    #[test]
    fn occluded_lights_fade_but_never_reach_zero() {
        for rule in
            [LightUpdateRule::UnoccludedAverage, LightUpdateRule::MeanContribution, LightUpdateRule::VisibilityRatio]
        {
            let mut g = guide(&[1.0, 1.0, 1.0], LightGuideSettings { rule, ..Default::default() });
            let cell = g.locate(Vec3::ONE).unwrap();
            for _ in 0..1000 {
                g.update(cell, 0, 1.0, false);
                g.update(cell, 1, 1.0, true);
                g.update(cell, 2, 0.1, true);
            }
            g.rebuild_sampling();
            let p: Vec<f32> = (0..3).map(|l| g.probability(cell, l)).collect();
            assert!(p[1] > p[0] && p.iter().all(|&x| x > 0.0), "{rule:?}: {p:?}");
            // Other cells learned nothing: power and uniform shares only.
            let far = g.locate(Vec3::new(3.9, 0.1, 0.1)).unwrap();
            assert_ne!(far, cell);
            let q = g.probability(far, 0);
            assert!((q - 1.0 / 3.0).abs() < 1e-6, "{q}");
        }
    }

    #[test]
    fn bad_input_is_rejected_and_counted() {
        let g = guide(&[1.0, 2.0], LightGuideSettings::default());
        let cell = g.locate(Vec3::ONE).unwrap();
        assert_eq!(g.update(cell, 0, f32::NAN, true), UpdateOutcome::RejectedNonFinite);
        assert_eq!(g.update(cell, 0, -1.0, true), UpdateOutcome::RejectedNegative);
        assert_eq!(g.update(cell, 9, 1.0, true), UpdateOutcome::OutsideDomain);
        assert_eq!(g.rejected_updates(), 2);
        assert_eq!(g.locate(Vec3::NAN), None);
        assert_eq!(g.locate(Vec3::splat(-1e30)), Some(LightCell(0)));
        assert_eq!(g.probability(cell, 9), 0.0);
        let error = |powers: &[f32], settings| LightGuide::new(Vec3::ZERO, Vec3::ONE, powers, settings).unwrap_err();
        assert!(matches!(error(&[], Default::default()), Error::InvalidSetting { name: "light_count", .. }));
        assert!(matches!(error(&[f32::NAN], Default::default()), Error::InvalidSetting { name: "light_powers", .. }));
        let tiny = LightGuideSettings { budget_bytes: 8, ..Default::default() };
        assert!(matches!(error(&[1.0], tiny), Error::BudgetTooSmall { .. }));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Whatever the powers (zeros, 1e-30 beside 1e30) and whatever was learned, every
        /// light keeps a positive selection probability in every cell, and they sum to one.
        #[test]
        fn no_light_is_ever_at_zero_probability(
            powers in proptest::collection::vec(proptest::prop_oneof![
                proptest::prelude::Just(0.0f32), 1e-30f32..1e-20, 0.0f32..10.0, 1e20f32..1e30], 1..300),
            updates in proptest::collection::vec((0u32..300, 0.0f32..1e30, proptest::bool::ANY), 0..200),
            rule in 0usize..3,
        ) {
            let rule = [LightUpdateRule::UnoccludedAverage, LightUpdateRule::MeanContribution, LightUpdateRule::VisibilityRatio][rule];
            let settings = LightGuideSettings { resolution: Some([2, 1, 1]), budget_bytes: 1 << 20, rule, ..Default::default() };
            let mut g = guide(&powers, settings);
            let cell = g.locate(Vec3::ZERO).unwrap();
            for &(light, contribution, unoccluded) in &updates {
                g.update(cell, light % powers.len() as u32, contribution, unoccluded);
            }
            g.rebuild_sampling();
            for c in 0..g.cell_count() as u32 {
                let total: f64 = (0..powers.len() as u32).map(|l| {
                    let p = g.probability(LightCell(c), l);
                    proptest::prop_assert!(p > 0.0, "cell {c}, light {l}: {p}");
                    Ok(p as f64)
                }).sum::<Result<f64, _>>()?;
                proptest::prop_assert!((total - 1.0).abs() < 1e-6, "cell {c}: {total}");
            }
        }
    }

    #[test]
    fn the_budget_sets_the_resolution_and_is_kept() {
        let settings = LightGuideSettings { budget_bytes: 64 << 10, ..Default::default() };
        let g = guide(&[1.0; 16], settings);
        let [x, y, z] = g.resolution();
        assert!(x >= y && y >= z && x * y * z >= 128, "{x}×{y}×{z}");
        assert!(g.cell_count() * 16 * ENTRY_BYTES <= settings.budget_bytes);
    }
}
