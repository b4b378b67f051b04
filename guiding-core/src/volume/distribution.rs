//! One region's sampling distribution: its leaf's CDF over the sphere, folded onto the
//! normal's hemisphere.

use glam::{Vec2, Vec3};

use crate::cdf::{cdf_probability, sample_cdf};
use crate::distribution::{fold_onto_hemisphere, folded_pdf, DirectionSample, DirectionalDistribution};

use super::sphere_layout::SphereLayout;

/// The sampling distribution of one region: its leaf's CDF over the sphere, folded onto
/// the normal's hemisphere.
#[derive(Clone, Copy, Debug)]
pub struct VolumeDistribution<'a> {
    pub(super) cdf: &'a [f32],
    pub(super) layout: SphereLayout,
    pub(super) normal: Vec3,
}

impl VolumeDistribution<'_> {
    fn sphere_pdf(&self, direction: Vec3) -> f32 {
        match self.layout.patch_of(direction) {
            Some(patch) => cdf_probability(self.cdf, patch) / self.layout.patch_solid_angle(),
            None => 0.0,
        }
    }
}

impl DirectionalDistribution for VolumeDistribution<'_> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let (patch, rest) = sample_cdf(self.cdf, u.x);
        let direction = fold_onto_hemisphere(self.layout.direction_in_patch(patch, Vec2::new(rest, u.y)), self.normal);
        DirectionSample { direction, pdf: self.pdf(direction) }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        folded_pdf(direction, self.normal, |d| self.sphere_pdf(d))
    }
}
