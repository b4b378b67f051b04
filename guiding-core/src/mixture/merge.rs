//! Merging two Gaussian mixtures learned over the same box with the same settings:
//! each region's lobe statistics averaged by observation counts, then refitted.

use core::sync::atomic::Ordering;

use super::guide::GaussianMixture;
use crate::error::Error;
use crate::update_rule::add_rejected_counts;

impl GaussianMixture {
    /// Adds what `other` learned. Both must cover the same box with the same settings,
    /// and neither may hold samples since its last
    /// [`rebuild_sampling`](crate::Guide::rebuild_sampling); otherwise nothing changes
    /// and the difference is named.
    ///
    /// Each region's mixture takes in the other's statistics by
    /// [`VmfMixture::merge`](super::VmfMixture::merge): lobes paired by nearest mean
    /// direction, their running statistics averaged by the two regions' observation
    /// counts, and the mixture refitted. An approximation (a fit has no exact sum): two
    /// processes' lobes may have divided their samples differently, and under the
    /// exponential or global learning rates the counts stand in for the rates' weights.
    pub fn merge(&mut self, other: &GaussianMixture) -> Result<(), Error> {
        if self.settings != other.settings {
            return Err(Error::Incompatible { what: "settings" });
        }
        if self.low != other.low || self.high != other.high || self.grid.resolution() != other.grid.resolution() {
            return Err(Error::Incompatible { what: "bounds" });
        }
        let pending = |guide: &GaussianMixture| {
            (0..guide.mixtures.len()).any(|region| guide.batch_row(region)[0].load(Ordering::Relaxed) > 0)
        };
        if pending(self) || pending(other) {
            return Err(Error::Incompatible { what: "samples pending since the last rebuild_sampling" });
        }
        for (mixture, theirs) in self.mixtures.iter_mut().zip(&other.mixtures) {
            mixture.merge(theirs);
        }
        add_rejected_counts(
            [&self.rejected_non_finite, &self.rejected_negative],
            [&other.rejected_non_finite, &other.rejected_negative],
        );
        self.epoch = self.epoch.max(other.epoch);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::distribution::DirectionalDistribution;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;
    use crate::mixture::GaussianMixtureSettings;

    fn mixture() -> GaussianMixture {
        GaussianMixture::new(Vec3::ZERO, Vec3::ONE, GaussianMixtureSettings::default()).expect("a mixture")
    }

    /// Epochs of light from `light` (a lobe of cos⁸) at the box's centre.
    fn learn(guide: &mut GaussianMixture, light: Vec3, seed: u64, epochs: u32) {
        let mut rng = Pcg32::new(seed, 1);
        let region = guide.locate(Vec3::splat(0.5), Vec3::Y).expect("inside");
        for _ in 0..epochs {
            for _ in 0..4000 {
                let s = guide.sample(region, rng.next_vec2());
                let target = 10.0 * s.direction.dot(light).max(0.0).powi(8);
                guide.update_sampled(region, s.direction, target, s.pdf);
            }
            guide.rebuild_sampling();
        }
    }

    #[test]
    fn halves_learned_apart_merge_into_a_mixture_that_finds_the_light() {
        let light = Vec3::new(0.6, 0.8, 0.0);
        let (mut a, mut b, mut all) = (mixture(), mixture(), mixture());
        learn(&mut a, light, 1, 4);
        learn(&mut b, light, 2, 4);
        learn(&mut all, light, 3, 8);
        let records = a.stats().accepted_updates + b.stats().accepted_updates;
        a.merge(&b).expect("same box and settings");
        assert_eq!(a.stats().accepted_updates, records);
        a.validate().expect("a valid mixture");
        let region = a.locate(Vec3::splat(0.5), Vec3::Y).unwrap();
        let (merged, learned) = (a.distribution(region).pdf(light), all.distribution(region).pdf(light));
        assert!(merged > 0.5 * learned && merged < 2.0 * learned, "{merged} against {learned}");
        assert!(merged > 10.0 * a.distribution(region).pdf(Vec3::new(-0.6, 0.8, 0.0)));
    }

    #[test]
    fn a_fresh_mixture_changes_nothing_and_other_mixtures_are_refused() {
        let mut learned = mixture();
        learn(&mut learned, Vec3::X, 4, 3);
        let before = learned.to_bytes();
        learned.merge(&mixture()).expect("same box and settings");
        assert_eq!(learned.to_bytes(), before, "a mixture with no observations adds nothing");
        let elsewhere =
            GaussianMixture::new(Vec3::ZERO, Vec3::splat(2.0), GaussianMixtureSettings::default()).expect("a mixture");
        assert_eq!(learned.merge(&elsewhere), Err(Error::Incompatible { what: "bounds" }));
        let busy = mixture();
        let region = busy.locate(Vec3::splat(0.5), Vec3::Y).unwrap();
        busy.update_sampled(region, Vec3::Y, 1.0, 0.5);
        let refused = learned.merge(&busy);
        assert_eq!(refused, Err(Error::Incompatible { what: "samples pending since the last rebuild_sampling" }));
        assert_eq!(learned.to_bytes(), before);
    }
}
