//! [`LightRecords`]: one thread's learning of a [`LightGuide`] during a pass, in tables of
//! its own. [`LightGuide::update`] does three locked read-modify-writes per shadow ray
//! on lines that every thread writes (many_lights 160×120: 12 % of nee's time);
//! [`LightGuide::record`] does plain adds here, and [`LightGuide::splat`] adds a thread's
//! tables to the guide between passes. The selection a pass reads is rebuilt only between
//! passes, so the pass draws the same lights either way.

use super::guide::LightGuide;
use super::settings::LightUpdateRule;
use crate::average_records::AverageRecords;
use crate::update_rule::UpdateOutcome;

/// One thread's shadow rays of a pass, per (cell, light) entry of a [`LightGuide`]: made
/// once per thread and kept from pass to pass (its tables, 16 bytes per entry, stop
/// growing after the first).
///
/// ```
/// use guiding_core::{glam::Vec3, LightGuide, LightGuideSettings, LightRecords};
/// let mut guide = LightGuide::new(Vec3::ZERO, Vec3::ONE, &[1.0, 1.0], LightGuideSettings::default()).unwrap();
/// let cell = guide.locate(Vec3::splat(0.5)).unwrap();
/// let mut records = LightRecords::default();
/// for _ in 0..100 {
///     guide.record(&mut records, cell, 0, 4.0, true);
///     guide.record(&mut records, cell, 1, 0.0, false);
/// }
/// guide.splat(&mut records);
/// guide.rebuild_sampling();
/// assert!(guide.probability(cell, 0) > guide.probability(cell, 1));
/// ```
#[derive(Clone, Debug, Default)]
pub struct LightRecords(AverageRecords);

impl LightRecords {
    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl LightGuide {
    /// [`update`](Self::update) into a thread's own `records`: the same checks and
    /// outcome, learned by the guide at [`splat`](Self::splat).
    #[inline]
    pub fn record(
        &self,
        records: &mut LightRecords,
        cell: super::LightCell,
        light: u32,
        contribution: f32,
        unoccluded: bool,
    ) -> UpdateOutcome {
        let Some(entry) = self.entry(cell, light) else { return UpdateOutcome::OutsideDomain };
        let learned = match self.learned(contribution, unoccluded) {
            Ok(learned) => learned,
            Err(rejected) => return rejected,
        };
        records.0.add(self.entry_count(), entry, learned);
        UpdateOutcome::Accepted
    }

    /// Adds what a thread's `records` hold to the guide and empties them: per entry the
    /// running average takes their targets as if [`update`](Self::update) had, in one
    /// step ((v·n + Σ) / (n + m)), and the counts add. Rebuild the selection after it.
    /// Records made for a guide of another size are dropped.
    pub fn splat(&mut self, records: &mut LightRecords) {
        let averages = self.settings.rule != LightUpdateRule::VisibilityRatio;
        let shots = &mut self.shots;
        records.0.splat(&mut self.values, &mut self.updates, averages, |entry, made| {
            let shots = shots[entry].get_mut();
            *shots = shots.saturating_add(made);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atomic_f32;
    use crate::lights::{LightCell, LightGuideSettings};
    use crate::low_discrepancy::Pcg32;
    use core::sync::atomic::Ordering;
    use glam::Vec3;

    /// Recording and splatting learns what updating in place learns: the same counts, and
    /// values equal to rounding, under every rule.
    #[test]
    fn records_splatted_learn_what_updates_learn() {
        for rule in
            [LightUpdateRule::UnoccludedAverage, LightUpdateRule::MeanContribution, LightUpdateRule::VisibilityRatio]
        {
            let settings = LightGuideSettings { rule, ..Default::default() };
            let powers = [1.0, 2.0, 0.5];
            let direct = LightGuide::new(Vec3::ZERO, Vec3::ONE, &powers, settings).unwrap();
            let mut splatted = LightGuide::new(Vec3::ZERO, Vec3::ONE, &powers, settings).unwrap();
            let (mut rng, mut records) = (Pcg32::new(8, 3), LightRecords::default());
            for pass in 0..3 {
                for _ in 0..5000 {
                    let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                    let cell = direct.locate(p).unwrap();
                    let light = (rng.next_f32() * 3.0) as u32;
                    let contribution = if pass == 1 && light == 2 { f32::NAN } else { rng.next_f32() * 10.0 };
                    let unoccluded = rng.next_f32() < 0.6;
                    let a = direct.update(cell, light, contribution, unoccluded);
                    let b = splatted.record(&mut records, cell, light, contribution, unoccluded);
                    assert_eq!(a, b);
                }
                assert_eq!(splatted.record(&mut records, LightCell(0), 7, 1.0, true), UpdateOutcome::OutsideDomain);
                // A cell past the grid is outside too, for update as for record (no panic).
                let past = LightCell(direct.cell_count() as u32);
                assert_eq!(direct.update(past, 0, 1.0, true), UpdateOutcome::OutsideDomain);
                assert_eq!(splatted.record(&mut records, past, 0, 1.0, true), UpdateOutcome::OutsideDomain);
                splatted.splat(&mut records);
                assert!(records.is_empty());
            }
            for i in 0..direct.entry_count() {
                let load = |g: &LightGuide| {
                    (
                        g.shots[i].load(Ordering::Relaxed),
                        g.updates[i].load(Ordering::Relaxed),
                        atomic_f32::load(&g.values[i]),
                    )
                };
                let ((s1, u1, v1), (s2, u2, v2)) = (load(&direct), load(&splatted));
                assert_eq!((s1, u1), (s2, u2), "{rule:?}: entry {i}");
                assert!((v1 - v2).abs() <= 1e-4 * v1.abs().max(1.0), "{rule:?}: entry {i}: {v1} against {v2}");
            }
            assert_eq!(direct.rejected.load(Ordering::Relaxed), splatted.rejected.load(Ordering::Relaxed));
        }
    }

    #[test]
    fn records_of_another_guide_are_dropped_and_start_over() {
        let settings = LightGuideSettings::default();
        let small = LightGuide::new(Vec3::ZERO, Vec3::ONE, &[1.0], settings).unwrap();
        let mut large = LightGuide::new(Vec3::ZERO, Vec3::ONE, &[1.0, 1.0], settings).unwrap();
        let mut records = LightRecords::default();
        small.record(&mut records, small.locate(Vec3::splat(0.5)).unwrap(), 0, 1.0, true);
        large.splat(&mut records);
        assert!(records.is_empty());
        assert_eq!(large.shots.iter().map(|s| s.load(Ordering::Relaxed)).sum::<u32>(), 0);
        // Recording for the large guide resizes the tables to it.
        let cell = large.locate(Vec3::splat(0.5)).unwrap();
        small.record(&mut records, small.locate(Vec3::splat(0.5)).unwrap(), 0, 1.0, true);
        large.record(&mut records, cell, 1, 1.0, true);
        large.splat(&mut records);
        assert_eq!(large.shots.iter().map(|s| s.load(Ordering::Relaxed)).sum::<u32>(), 1);
    }
}
