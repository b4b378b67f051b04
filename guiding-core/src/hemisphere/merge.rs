//! Merging and resetting a [`HemisphereGrid`]: what another process learned added, or
//! everything learned forgotten.

use core::sync::atomic::Ordering;

use super::grid::{GridState, HemisphereGrid};
use crate::atomic_f32;
use crate::error::Error;
use crate::update_rule::add_rejected_counts;

impl HemisphereGrid {
    /// Adds what `other` learned to this grid, as if its updates had been made here: each
    /// patch's Q becomes the two Q's mean weighted by their update weights (the simple
    /// average's denominators), and visits, weights and rejection counts add up; the
    /// sampling CDFs are rebuilt. Both grids must have been built over the same scene
    /// with the same settings (same probes, same patches); otherwise nothing changes and
    /// the first difference is named.
    ///
    /// Exact for [`LearningRate::SimpleAverage`](crate::LearningRate::SimpleAverage)
    /// (what a render farm's nodes learn from different paths merges into the grid one
    /// process would have learned from all of them) while both grids are in memory; a
    /// loaded grid weighs each past update 1, so after a save and load the merge is exact
    /// for `update` and approximate for `update_sampled`. For the other learning rates
    /// the weighted mean is an approximation.
    pub fn merge(&mut self, other: &HemisphereGrid) -> Result<(), Error> {
        if self.settings != other.settings {
            return Err(Error::Incompatible { what: "settings" });
        }
        if self.positions != other.positions || self.normals != other.normals {
            return Err(Error::Incompatible { what: "probes" });
        }
        let entries = self.q.iter().zip(&self.patch_weights).zip(&self.patch_visits);
        let theirs = other.q.iter().zip(&other.patch_weights).zip(&other.patch_visits);
        for (((q, weight), visits), ((other_q, other_weight), other_visits)) in entries.zip(theirs) {
            let (w, w_other) = (atomic_f32::load(weight) as f64, atomic_f32::load(other_weight) as f64);
            if w_other > 0.0 {
                let merged =
                    (atomic_f32::load(q) as f64 * w + atomic_f32::load(other_q) as f64 * w_other) / (w + w_other);
                q.store((merged as f32).to_bits(), Ordering::Relaxed);
                weight.store(((w + w_other).min(f32::MAX as f64) as f32).to_bits(), Ordering::Relaxed);
            }
            let sum = visits.load(Ordering::Relaxed).saturating_add(other_visits.load(Ordering::Relaxed));
            visits.store(sum, Ordering::Relaxed);
        }
        for (visits, other_visits) in self.probe_visits.iter().zip(&other.probe_visits) {
            visits.store(
                visits.load(Ordering::Relaxed).saturating_add(other_visits.load(Ordering::Relaxed)),
                Ordering::Relaxed,
            );
        }
        add_rejected_counts(
            [&self.rejected_non_finite, &self.rejected_negative],
            [&other.rejected_non_finite, &other.rejected_negative],
        );
        self.epoch = self.epoch.max(other.epoch);
        self.build_cdfs(true);
        Ok(())
    }

    /// Forgets everything learned: every Q back to `initial_q`, every count to 0, epoch
    /// 0; the probes stay. Equals a grid freshly built over the same surfaces.
    pub fn reset(&mut self) {
        let entries = self.q.len();
        let state = GridState {
            probe_spacing: self.probe_spacing,
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            probe_visits: alloc::vec![0; self.positions.len()],
            q: alloc::vec![self.settings.initial_q; entries],
            patch_visits: alloc::vec![0; entries],
            cdf: None,
            epoch: 0,
            rejected_non_finite: 0,
            rejected_negative: 0,
        };
        *self = Self::assemble(self.settings, state);
    }
}

#[cfg(test)]
mod tests {
    use alloc::vec;
    use alloc::vec::Vec;

    use glam::Vec3;

    use super::*;
    use crate::guide::Guide;
    use crate::hemisphere::grid::tests::one_probe;
    use crate::hemisphere::{HemisphereGridSettings, ProbeSet};

    /// Resetting forgets every update: the grid serializes as one freshly built.
    #[test]
    fn reset_gives_the_grid_built_fresh() {
        let positions: Vec<Vec3> = (0..12).map(|i| Vec3::new((i % 4) as f32, 0.0, (i / 4) as f32 * 0.7)).collect();
        let probes = ProbeSet { normals: vec![Vec3::Y; positions.len()], positions, spacing: 0.7 };
        let settings = HemisphereGridSettings::default();
        let fresh = HemisphereGrid::from_probes(&probes, settings).unwrap();
        let mut grid = HemisphereGrid::from_probes(&probes, settings).unwrap();
        let probe = grid.locate(Vec3::new(2.1, 0.0, 0.6), Vec3::Y).unwrap();
        for i in 0..100 {
            grid.update(probe, Vec3::new(0.1 * (i % 7) as f32, 1.0, 0.0).normalize(), 5.0);
        }
        grid.update(probe, Vec3::Y, f32::NAN);
        grid.rebuild_sampling();
        assert_ne!(grid.to_bytes(), fresh.to_bytes());
        grid.reset();
        assert_eq!(grid.to_bytes(), fresh.to_bytes());
    }

    /// Two grids that each learned half of a stream, merged, hold what one grid learned
    /// from all of it (simple average, weighted and unweighted updates alike); a grid of
    /// other probes is refused and left as it was.
    #[test]
    fn merging_halves_gives_the_grid_that_learned_everything() {
        use crate::low_discrepancy::Pcg32;
        let (mut first, probe) = one_probe(HemisphereGridSettings::default());
        let (second, _) = one_probe(HemisphereGridSettings::default());
        let (all, _) = one_probe(HemisphereGridSettings::default());
        let mut rng = Pcg32::new(7, 1);
        for i in 0..20_000 {
            let u = rng.next_vec2();
            let direction = Vec3::new(u.x - 0.5, u.y - 0.5, 0.2 + rng.next_f32()).normalize();
            let (target, pdf) = (10.0 * rng.next_f32() * direction.z, 0.1 + rng.next_f32());
            let half = if i % 3 == 0 { &second } else { &first };
            if i % 2 == 0 {
                half.update_sampled(probe, direction, target, pdf);
                all.update_sampled(probe, direction, target, pdf);
            } else {
                half.update(probe, direction, target);
                all.update(probe, direction, target);
            }
        }
        first.merge(&second).unwrap();
        assert_eq!(first.stats().accepted_updates, all.stats().accepted_updates);
        for patch in 0..first.patch_count() {
            let (merged, single) = (first.q(probe, patch), all.q(probe, patch));
            assert!(
                (merged - single).abs() <= 1e-4 * single.abs().max(1.0),
                "patch {patch}: {merged} against {single}"
            );
        }
        let probes = ProbeSet { positions: vec![Vec3::X], normals: vec![Vec3::Z], spacing: 1.0 };
        let elsewhere = HemisphereGrid::from_probes(&probes, HemisphereGridSettings::default()).unwrap();
        let before = first.stats();
        let refused = first.merge(&elsewhere).unwrap_err();
        assert!(alloc::format!("{refused}").contains("probes"), "{refused}");
        assert_eq!(first.stats(), before);
    }
}
