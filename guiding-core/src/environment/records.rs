//! [`EnvRecords`]: one thread's learning of an [`EnvTileGuide`] during a pass, in tables
//! of its own. [`EnvTileGuide::update`] does two locked read-modify-writes per shadow ray
//! on lines that every thread writes; [`EnvTileGuide::record`] does plain adds here, and
//! [`EnvTileGuide::splat`] adds a thread's tables to the guide between passes. The
//! distribution a pass reads is rebuilt only between passes, so the pass draws the same
//! directions either way.

use super::guide::{EnvCell, EnvSample, EnvTileGuide};
use crate::average_records::{AverageRecords, Learned};
use crate::update_rule::UpdateOutcome;

/// One thread's environment shadow rays of a pass, per (cell, lobe) entry of an
/// [`EnvTileGuide`]: made once per thread and kept from pass to pass (its tables, 16 bytes
/// per entry, stop growing after the first).
///
/// ```
/// use guiding_core::environment::{EnvRecords, EnvTileGuide, EnvTileGuideSettings, EnvironmentTiles};
/// use guiding_core::DirectionalDistribution;
/// use glam::{Vec2, Vec3};
///
/// let tiles = EnvironmentTiles::new(8, 4, &[1.0; 32], [4, 2])?;
/// let mut guide = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, None, EnvTileGuideSettings::default())?;
/// let cell = guide.locate(Vec3::splat(0.5)).expect("finite");
/// let mut records = EnvRecords::default();
/// // Only light from straight up (+y) ever arrives in this cell.
/// for i in 0..1000 {
///     let s = guide.distribution(cell).sample_lobe(0.37 * i as f32 % 1.0, Vec2::new(0.5, 0.5));
///     guide.record(&mut records, cell, &s, if s.direction.y > 0.0 { 1.0 } else { 0.0 });
/// }
/// guide.splat(&mut records);
/// guide.rebuild_sampling();
/// let up = guide.distribution(cell).pdf(Vec3::new(0.1, 0.9, 0.0).normalize());
/// let down = guide.distribution(cell).pdf(Vec3::new(0.1, -0.9, 0.0).normalize());
/// assert!(up > 5.0 * down && down > 0.0);
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Clone, Debug, Default)]
pub struct EnvRecords(AverageRecords);

impl EnvRecords {
    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl EnvTileGuide {
    /// [`update`](Self::update) into a thread's own `records`: the same checks and
    /// outcome, learned by the guide at [`splat`](Self::splat).
    #[inline]
    pub fn record(&self, records: &mut EnvRecords, cell: EnvCell, sample: &EnvSample, integrand: f32) -> UpdateOutcome {
        match self.target(cell, sample, integrand) {
            Ok((entry, target)) => {
                records.0.add(self.entry_count(), entry, Learned::Target(target));
                UpdateOutcome::Accepted
            }
            Err(outcome) => outcome,
        }
    }

    /// Adds what a thread's `records` hold to the guide and empties them: per entry the
    /// running average takes their targets as if [`update`](Self::update) had, in one
    /// step ((v·n + Σ) / (n + m)), and the counts add. Rebuild the sampling after it.
    /// Records made for a guide of another size are dropped.
    pub fn splat(&mut self, records: &mut EnvRecords) {
        records.0.splat(&mut self.values, &mut self.updates, true, |_, _| {});
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atomic_f32;
    use crate::environment::{EnvTileGuideSettings, EnvironmentTiles};
    use crate::low_discrepancy::Pcg32;
    use core::sync::atomic::Ordering;
    use glam::{Vec2, Vec3};

    fn guide() -> EnvTileGuide {
        let texels: alloc::vec::Vec<f32> = (0..32).map(|i| 1.0 + (i % 5) as f32).collect();
        let tiles = EnvironmentTiles::new(8, 4, &texels, [4, 2]).unwrap();
        EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, None, EnvTileGuideSettings::default()).unwrap()
    }

    /// Recording and splatting learns what updating in place learns: the same counts, and
    /// the same values to rounding; refused samples are refused alike.
    #[test]
    fn records_splatted_learn_what_updates_learn() {
        let (direct, mut splatted) = (guide(), guide());
        let (mut rng, mut records) = (Pcg32::new(4, 9), EnvRecords::default());
        for pass in 0..3 {
            for _ in 0..5000 {
                let cell = direct.locate(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())).unwrap();
                let s =
                    direct.distribution(cell).sample_lobe(rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
                let integrand = if pass == 1 && s.lobe.0 == 2 { f32::INFINITY } else { rng.next_f32() * 3.0 };
                assert_eq!(direct.update(cell, &s, integrand), splatted.record(&mut records, cell, &s, integrand));
            }
            let outside =
                EnvSample { lobe_pdf: 0.0, ..direct.distribution(EnvCell(0)).sample_lobe(0.5, Vec2::splat(0.5)) };
            assert_eq!(splatted.record(&mut records, EnvCell(0), &outside, 1.0), UpdateOutcome::OutsideDomain);
            splatted.splat(&mut records);
            assert!(records.is_empty());
        }
        let (dv, du) = (&direct.values, &direct.updates);
        for i in 0..dv.len() {
            assert_eq!(du[i].load(Ordering::Relaxed), splatted.updates[i].load(Ordering::Relaxed), "entry {i}");
            let (v1, v2) = (atomic_f32::load(&dv[i]), atomic_f32::load(&splatted.values[i]));
            assert!((v1 - v2).abs() <= 1e-4 * v1.abs().max(1.0), "entry {i}: {v1} against {v2}");
        }
        assert!(direct.rejected.load(Ordering::Relaxed) > 0);
        assert_eq!(direct.rejected.load(Ordering::Relaxed), splatted.rejected.load(Ordering::Relaxed));
    }

    /// Records made for a guide of another size teach nothing and leave the records empty.
    #[test]
    fn records_of_another_guide_are_dropped() {
        let small = guide();
        let tiles = EnvironmentTiles::new(8, 4, &[1.0; 32], [8, 4]).unwrap();
        let mut large = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, None, EnvTileGuideSettings::default()).unwrap();
        let mut records = EnvRecords::default();
        let cell = small.locate(Vec3::splat(0.5)).unwrap();
        let s = small.distribution(cell).sample_lobe(0.3, Vec2::splat(0.5));
        small.record(&mut records, cell, &s, 1.0);
        large.splat(&mut records);
        assert!(records.is_empty());
        assert_eq!(large.updates.iter().map(|u| u.load(Ordering::Relaxed)).sum::<u32>(), 0);
        // The dropped records leave nothing behind: the same records, made again for a
        // guide of their own size, teach it exactly what updating in place teaches.
        let (direct, mut splatted) = (guide(), guide());
        assert_eq!(direct.update(cell, &s, 3.0), splatted.record(&mut records, cell, &s, 3.0));
        splatted.splat(&mut records);
        for i in 0..direct.values.len() {
            assert_eq!(direct.updates[i].load(Ordering::Relaxed), splatted.updates[i].load(Ordering::Relaxed));
            assert_eq!(atomic_f32::load(&direct.values[i]), atomic_f32::load(&splatted.values[i]), "entry {i}");
        }
    }
}
