//! [`SphereLayout`]: the whole sphere cut into equal-area patches (Lambert's cylindrical
//! projection: equal steps in z = cos θ and in φ), in world axes.

use core::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::atan2::fast_atan2;
use crate::error::{require, Error};

/// Patches of equal solid angle 4π/(nz·nφ): `resolution[0]` bands of z = cos θ about the
/// world z axis, `resolution[1]` sectors of φ.
///
/// ```
/// use guiding_core::volume::SphereLayout;
/// use glam::{Vec2, Vec3};
/// let layout = SphereLayout { resolution: [16, 16] };
/// let k = layout.patch_of(Vec3::new(0.3, -0.4, 0.866)).unwrap();
/// let d = layout.direction_in_patch(k, Vec2::new(0.5, 0.5));
/// assert_eq!(layout.patch_of(d), Some(k));
/// assert!((layout.patch_solid_angle() * 256.0 - 4.0 * std::f32::consts::PI).abs() < 1e-5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SphereLayout {
    /// Bands in z and sectors in φ, each in 1..=256.
    pub resolution: [u32; 2],
}

impl Default for SphereLayout {
    /// 16 × 16 = 256 patches: the angular resolution of an 8 × 16 hemisphere.
    fn default() -> Self {
        Self { resolution: [16, 16] }
    }
}

impl SphereLayout {
    /// Checks the resolution.
    pub fn validate(&self) -> Result<(), Error> {
        let [nz, nphi] = self.resolution;
        require((1..=256).contains(&nz), "sphere_layout.resolution[0]", nz as f64, "in 1..=256")?;
        require((1..=256).contains(&nphi), "sphere_layout.resolution[1]", nphi as f64, "in 1..=256")
    }

    /// Number of patches.
    pub fn patch_count(&self) -> usize {
        (self.resolution[0] * self.resolution[1]) as usize
    }

    /// Solid angle of every patch, steradians.
    pub fn patch_solid_angle(&self) -> f32 {
        4.0 * PI / self.patch_count() as f32
    }

    /// The patch holding unit `direction`, or `None` for a non-finite or zero one.
    #[inline]
    pub fn patch_of(&self, direction: Vec3) -> Option<usize> {
        let d = direction.try_normalize()?;
        let [nz, nphi] = self.resolution;
        let band = (((d.z + 1.0) * 0.5 * nz as f32) as u32).min(nz - 1);
        let mut phi = fast_atan2(d.y, d.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let sector = ((phi * (0.5 / PI) * nphi as f32) as u32).min(nphi - 1);
        Some((band * nphi + sector) as usize)
    }

    /// The direction at `u` ∈ [0, 1)² inside patch `patch`, uniform in solid angle.
    #[inline]
    pub fn direction_in_patch(&self, patch: usize, u: Vec2) -> Vec3 {
        let [nz, nphi] = self.resolution;
        let (band, sector) = (patch as u32 / nphi, patch as u32 % nphi);
        let z = (-1.0 + 2.0 * (band as f32 + u.x) / nz as f32).clamp(-1.0, 1.0);
        let phi = 2.0 * PI * (sector as f32 + u.y) / nphi as f32;
        let r = libm::sqrtf((1.0 - z * z).max(0.0));
        let (sin_phi, cos_phi) = libm::sincosf(phi);
        Vec3::new(r * cos_phi, r * sin_phi, z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn directions_land_in_their_patch_and_every_patch_is_reached() {
        let layout = SphereLayout { resolution: [7, 12] };
        let mut rng = Pcg32::new(3, 3);
        let mut hits = alloc::vec![0u32; layout.patch_count()];
        for (k, count) in hits.iter_mut().enumerate() {
            for _ in 0..20 {
                // Stay off the borders, where rounding may pick the neighbour.
                let u = Vec2::new(0.02 + 0.96 * rng.next_f32(), 0.02 + 0.96 * rng.next_f32());
                let d = layout.direction_in_patch(k, u);
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert_eq!(layout.patch_of(d), Some(k));
                *count += 1;
            }
        }
        assert!(hits.iter().all(|&h| h == 20));
        assert_eq!(layout.patch_of(Vec3::NAN), None);
        assert_eq!(layout.patch_of(Vec3::ZERO), None);
        assert!(layout.patch_of(Vec3::Z).is_some() && layout.patch_of(-Vec3::Z).is_some());
        assert!(SphereLayout { resolution: [0, 4] }.validate().is_err());
    }
}
