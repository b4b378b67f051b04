//! Merging two irradiance volumes built over the same box with the same settings: the
//! union of their octrees, each patch the two Q's mean weighted by their update weights.

use core::sync::atomic::Ordering;

use super::guide::{IrradianceVolume, LEAF};
use crate::atomic_f32;
use crate::error::Error;
use crate::update_rule::add_rejected_counts;

impl IrradianceVolume {
    /// Adds what `other` learned. Both must cover the same box with the same settings
    /// (the same initial grid); otherwise nothing changes and the difference is named.
    ///
    /// The octrees are merged into their union: where `other` split a leaf that this
    /// volume did not, this leaf splits too (its children inherit its Q and an eighth
    /// of its visits and weights, as a split by learning does), while the byte budget
    /// holds; past the budget the leaf keeps its size and takes in every leaf of
    /// `other` below it. Where this volume split and `other` did not, each child takes
    /// in an eighth of `other`'s leaf. Each patch then becomes the mean of both Q's
    /// weighted by their update weights (the simple average's denominators), and the
    /// visits add up.
    ///
    /// Where both octrees have the same shape this is [`HemisphereGrid::merge`]'s rule,
    /// exact for [`LearningRate::SimpleAverage`](crate::LearningRate::SimpleAverage)
    /// while both are in memory. Where their shapes differ it is an approximation: a
    /// leaf split later had learned its parent's Q for all its earlier updates, so an
    /// eighth of a coarse leaf stands in for what a finer one would have learned.
    ///
    /// [`HemisphereGrid::merge`]: crate::HemisphereGrid::merge
    pub fn merge(&mut self, other: &IrradianceVolume) -> Result<(), Error> {
        if self.settings != other.settings {
            return Err(Error::Incompatible { what: "settings" });
        }
        if self.low != other.low || self.high != other.high || self.grid.resolution() != other.grid.resolution() {
            return Err(Error::Incompatible { what: "bounds" });
        }
        for cell in 0..self.grid.cell_count() {
            self.merge_entry(cell as u32, other, other.nodes[cell], 1);
        }
        add_rejected_counts(
            [&self.rejected_non_finite, &self.rejected_negative],
            [&other.rejected_non_finite, &other.rejected_negative],
        );
        self.epoch = self.epoch.max(other.epoch);
        self.build_cdfs(true);
        Ok(())
    }

    /// Merges `other`'s tree entry `theirs` into this volume's tree entry `node`;
    /// `other`'s counts there weigh 1/`divisor` (an eighth per level of its leaf that
    /// this volume's split children share).
    fn merge_entry(&mut self, node: u32, other: &IrradianceVolume, theirs: u32, divisor: u32) {
        let mine = self.nodes[node as usize];
        match (mine & LEAF != 0, theirs & LEAF != 0) {
            (true, true) => self.take_in(mine & !LEAF, other, theirs & !LEAF, divisor),
            (false, true) => {
                for octant in 0..8 {
                    self.merge_entry(mine + octant, other, theirs, divisor.saturating_mul(8));
                }
            }
            (true, false) => {
                if self.memory_bytes() + self.split_bytes() <= self.settings.budget_bytes {
                    self.split_leaf_at(node);
                    let first = self.nodes[node as usize];
                    for octant in 0..8 {
                        self.merge_entry(first + octant, other, other.nodes[(theirs + octant) as usize], divisor);
                    }
                } else {
                    // No room to follow `other` down: this leaf takes in all of it.
                    for octant in 0..8 {
                        self.merge_entry(node, other, other.nodes[(theirs + octant) as usize], divisor);
                    }
                }
            }
            (false, false) => {
                for octant in 0..8 {
                    self.merge_entry(mine + octant, other, other.nodes[(theirs + octant) as usize], divisor);
                }
            }
        }
    }

    /// Takes `other`'s leaf `theirs`, its counts divided by `divisor`, into leaf `leaf`.
    fn take_in(&mut self, leaf: u32, other: &IrradianceVolume, theirs: u32, divisor: u32) {
        let patches = self.patch_count();
        let floor = self.settings.q_floor;
        let (mine, from) = (leaf as usize * patches, theirs as usize * patches);
        for k in 0..patches {
            let (i, j) = (mine + k, from + k);
            let w = atomic_f32::load(&self.patch_weights[i]) as f64;
            let w_other = atomic_f32::load(&other.patch_weights[j]) as f64 / divisor as f64;
            if w_other > 0.0 {
                let q = atomic_f32::load(&self.q[i]) as f64;
                let q_other = atomic_f32::load(&other.q[j]) as f64;
                let merged = ((q * w + q_other * w_other) / (w + w_other)) as f32;
                let merged = if merged.is_finite() { merged.max(floor) } else { floor };
                self.q[i].store(merged.to_bits(), Ordering::Relaxed);
                let weight = (w + w_other).min(f32::MAX as f64) as f32;
                self.patch_weights[i].store(weight.to_bits(), Ordering::Relaxed);
            }
            let visits = other.patch_visits[j].load(Ordering::Relaxed) / divisor;
            let sum = self.patch_visits[i].load(Ordering::Relaxed).saturating_add(visits);
            self.patch_visits[i].store(sum, Ordering::Relaxed);
        }
        let visits = other.leaf_visits[theirs as usize].load(Ordering::Relaxed) / divisor;
        let slot = &self.leaf_visits[leaf as usize];
        slot.store(slot.load(Ordering::Relaxed).saturating_add(visits), Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;
    use crate::volume::IrradianceVolumeSettings;
    use crate::{DirectionalDistribution, LearningRate};

    fn volume(budget_bytes: usize) -> IrradianceVolume {
        let settings = IrradianceVolumeSettings { budget_bytes, ..IrradianceVolumeSettings::default() };
        IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a volume over the unit box")
    }

    /// Teaches `count` updates of a light along +x at points drawn from `rng`.
    fn teach(volume: &IrradianceVolume, rng: &mut Pcg32, count: u32) {
        for _ in 0..count {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let region = volume.locate(p, Vec3::Y).expect("inside");
            let s = volume.distribution(region).sample(rng.next_vec2());
            let target = 10.0 * s.direction.x.max(0.0).powi(8) * (1.0 + p.x);
            volume.update_sampled(region, s.direction, target, s.pdf);
        }
    }

    #[test]
    fn volumes_of_one_shape_merge_into_the_one_that_learned_every_update() {
        let settings = IrradianceVolumeSettings::default();
        assert_eq!(settings.update_rule.learning_rate, LearningRate::SimpleAverage);
        let (all, mut a, b) = (volume(1 << 20), volume(1 << 20), volume(1 << 20));
        // The same updates, taught to one volume and split between two: the shapes stay
        // the grid's, so the merge is exact up to rounding.
        for round in 0..2 {
            let mut half = Pcg32::new(9 + round, 1);
            let mut copy = Pcg32::new(9 + round, 1);
            teach(if round == 0 { &a } else { &b }, &mut half, 5_000);
            teach(&all, &mut copy, 5_000);
        }
        a.merge(&b).expect("same settings and box");
        for (x, y) in a.q_values().iter().zip(all.q_values()) {
            let (x, y) = (atomic_f32::load(x), atomic_f32::load(y));
            assert!((x - y).abs() <= 1e-4 * y.abs().max(1e-3), "{x} against {y}");
        }
    }

    #[test]
    fn a_coarse_volume_follows_a_finer_one_and_a_fresh_one_changes_nothing() {
        let settings =
            IrradianceVolumeSettings { split_updates_per_patch: 0.5, budget_bytes: 1 << 21, ..Default::default() };
        let fine = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a volume");
        let mut rng = Pcg32::new(5, 6);
        teach(&fine, &mut rng, 40_000);
        let mut fine = fine;
        fine.rebuild_sampling();
        assert!(fine.leaf_count() > fine.grid.cell_count(), "the fine volume split");
        let mut coarse = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a volume");
        coarse.merge(&fine).expect("same settings and box");
        assert_eq!(coarse.node_count(), fine.node_count(), "the union follows the finer tree");
        let p = Vec3::new(0.9, 0.5, 0.5);
        let (r_fine, r_merged) = (fine.locate(p, Vec3::Y).unwrap(), coarse.locate(p, Vec3::Y).unwrap());
        let d = Vec3::new(0.95, 0.3, 0.0).normalize();
        let (pf, pm) = (fine.distribution(r_fine).pdf(d), coarse.distribution(r_merged).pdf(d));
        assert!(pm > 0.5 * pf && pm < 2.0 * pf, "merged pdf {pm} against the learned {pf}");
        // Merging a fresh volume in leaves what was learned alone.
        let before: alloc::vec::Vec<f32> = fine.q_values().iter().map(atomic_f32::load).collect();
        let fresh = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a volume");
        fine.merge(&fresh).expect("same settings and box");
        let after: alloc::vec::Vec<f32> = fine.q_values().iter().map(atomic_f32::load).collect();
        assert_eq!(before, after);
    }

    #[test]
    fn merging_past_the_budget_keeps_the_budget_and_other_shapes_are_refused() {
        let settings = IrradianceVolumeSettings { split_updates_per_patch: 0.5, ..Default::default() };
        let budget = settings.budget_bytes;
        let fine = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a volume");
        let mut rng = Pcg32::new(7, 8);
        teach(&fine, &mut rng, 200_000);
        let mut fine = fine;
        for _ in 0..4 {
            teach(&fine, &mut rng, 100_000);
            fine.rebuild_sampling();
        }
        // Another volume that split elsewhere: their union would not fit.
        let other = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, settings).expect("a volume");
        for _ in 0..200_000 {
            let p = Vec3::new(0.1 * rng.next_f32(), rng.next_f32(), rng.next_f32());
            let region = other.locate(p, Vec3::Y).expect("inside");
            other.update(region, Vec3::X, 1.0);
        }
        let mut other = other;
        other.rebuild_sampling();
        fine.merge(&other).expect("same settings and box");
        assert!(fine.memory_bytes() <= budget, "{} bytes past {budget}", fine.memory_bytes());
        fine.validate().expect("a valid volume");
        let elsewhere = IrradianceVolume::new(Vec3::ZERO, Vec3::splat(2.0), settings).expect("a volume");
        assert_eq!(fine.merge(&elsewhere), Err(Error::Incompatible { what: "bounds" }));
        let coarser = IrradianceVolumeSettings { budget_bytes: budget / 2, ..settings };
        let smaller = IrradianceVolume::new(Vec3::ZERO, Vec3::ONE, coarser).expect("a volume");
        assert_eq!(fine.merge(&smaller), Err(Error::Incompatible { what: "settings" }));
    }
}
