//! [`ProbeDistribution`]: one probe's sampling distribution, a CDF over its patches.

use glam::{Vec2, Vec3};

use super::mapping::PatchLayout;
use crate::cdf::{cdf_probability, sample_cdf};
use crate::distribution::{DirectionSample, DirectionalDistribution};
use crate::frame::Frame;

/// One probe's sampling distribution: its CDF over patches, then uniform in the patch.
#[derive(Clone, Copy, Debug)]
pub struct ProbeDistribution<'a> {
    pub(crate) cdf: &'a [f32],
    pub(crate) frame: Frame,
    pub(crate) layout: PatchLayout,
}

impl ProbeDistribution<'_> {
    /// pdf per steradian of a direction in patch `patch`: P(patch) / ΔΩ.
    fn patch_pdf(&self, patch: usize) -> f32 {
        cdf_probability(self.cdf, patch) / self.layout.patch_solid_angle()
    }
}

impl DirectionalDistribution for ProbeDistribution<'_> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let (patch, u_in_patch) = sample_cdf(self.cdf, u.x);
        let local = self.layout.direction_in_patch(patch, Vec2::new(u_in_patch, u.y));
        DirectionSample { direction: self.frame.to_world(local), pdf: self.patch_pdf(patch) }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        match self.layout.patch_of(self.frame.to_local(direction)) {
            Some(patch) => self.patch_pdf(patch),
            None => 0.0,
        }
    }
}
