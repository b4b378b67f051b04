//! [`SunDisk`]: a small bright disk in the environment, sampled on its own (uniformly
//! over its cone of directions).

use core::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::error::{require, Error};
use crate::frame::Frame;

/// The sun: a disk of uniform radiance seen under a small cone of directions.
///
/// ```
/// use guiding_core::environment::SunDisk;
/// use glam::{Vec2, Vec3};
/// let sun = SunDisk::new(Vec3::new(0.0, 1.0, -1.0), 0.5f32.to_radians(), 2.0e4)?;
/// let d = sun.sample(Vec2::new(0.3, 0.8));
/// assert!(sun.contains(d));
/// assert!((sun.pdf() * sun.solid_angle() - 1.0).abs() < 1e-5);
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunDisk {
    frame: Frame,
    direction: Vec3,
    /// 1 − cos of the angular radius, kept apart: for a disk of a degree or less, cos
    /// rounds to within a few f32 steps of 1.
    one_minus_cos: f32,
    /// Luminance of its radiance.
    luminance: f32,
}

impl SunDisk {
    /// A disk centred on `direction` (any length > 0) with the given angular radius
    /// (radians, in [1.1·10⁻¹⁹, π/2]: smaller ones have no solid angle in f32) and
    /// radiance luminance (finite, ≥ 0).
    pub fn new(direction: Vec3, angular_radius: f32, luminance: f32) -> Result<Self, Error> {
        let length = direction.length();
        require(direction.is_finite() && length > 0.0, "sun.direction", length as f64, "finite and non-zero")?;
        let radius = angular_radius as f64;
        let valid = angular_radius > 0.0 && angular_radius <= core::f32::consts::FRAC_PI_2;
        require(valid, "sun.angular_radius", radius, "in (0, π/2]")?;
        require(luminance.is_finite() && luminance >= 0.0, "sun.luminance", luminance as f64, "finite and ≥ 0")?;
        let direction = direction / length;
        let half = libm::sinf(0.5 * angular_radius);
        // A disk so small that 1 − cos rounds to 0 (or a denormal) has no finite density.
        let one_minus_cos = 2.0 * half * half;
        require(
            one_minus_cos >= f32::MIN_POSITIVE,
            "sun.angular_radius",
            radius,
            "at least 1.1e-19 (a solid angle f32 holds)",
        )?;
        Ok(Self { frame: Frame::from_normal(direction), direction, one_minus_cos, luminance })
    }

    /// The unit direction towards its centre.
    pub fn direction(&self) -> Vec3 {
        self.direction
    }

    /// Its solid angle, steradians.
    pub fn solid_angle(&self) -> f32 {
        2.0 * PI * self.one_minus_cos
    }

    /// Luminance of its radiance.
    pub fn luminance(&self) -> f32 {
        self.luminance
    }

    /// Luminance × solid angle: its power in the units of an environment tile's.
    pub fn power(&self) -> f32 {
        self.luminance * self.solid_angle()
    }

    /// Whether unit direction `d` lies inside the disk: |d − centre|² = 2(1 − cos θ),
    /// exact where cos θ itself would round to 1.
    #[inline]
    pub fn contains(&self, d: Vec3) -> bool {
        (d - self.direction).length_squared() <= 2.0 * self.one_minus_cos
    }

    /// Density per steradian of [`sample`](Self::sample) inside the disk.
    #[inline]
    pub fn pdf(&self) -> f32 {
        1.0 / self.solid_angle()
    }

    /// A direction uniform over the disk from two uniform numbers in [0, 1).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let one_minus_cos = u.x * self.one_minus_cos;
        let sin_theta = libm::sqrtf((one_minus_cos * (2.0 - one_minus_cos)).max(0.0));
        let (sin_phi, cos_phi) = libm::sincosf(2.0 * PI * u.y);
        let local = Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, 1.0 - one_minus_cos);
        let d = self.frame.to_world(local).normalize();
        // Rounding can leave a direction drawn at the rim just outside the disk (for a
        // disk narrower than f32 directions resolve, nearly all of them), where its pdf
        // has no sun term. The centre has the same radiance and density as the rest of
        // the disk, so it stands in.
        if self.contains(d) {
            d
        } else {
            self.direction
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn samples_stay_inside_even_for_a_tiny_disk() {
        for radius_deg in [0.05f32, 0.27, 5.0, 90.0] {
            let sun = SunDisk::new(Vec3::new(0.3, 0.8, -0.5), radius_deg.to_radians(), 1.0).unwrap();
            let mut rng = Pcg32::new(1, 2);
            let inside = (0..100_000).filter(|_| sun.contains(sun.sample(rng.next_vec2()))).count();
            assert_eq!(inside, 100_000, "{radius_deg}°");
            let expected = 2.0 * core::f64::consts::PI * (1.0 - libm::cos((radius_deg as f64).to_radians()));
            assert!((sun.solid_angle() as f64 - expected).abs() <= 1e-4 * expected, "{radius_deg}°");
        }
    }

    #[test]
    fn bad_suns_are_rejected_by_name() {
        let name = |e: Error| match e {
            Error::InvalidSetting { name, .. } => name,
            _ => "",
        };
        assert_eq!(name(SunDisk::new(Vec3::ZERO, 0.1, 1.0).unwrap_err()), "sun.direction");
        assert_eq!(name(SunDisk::new(Vec3::Y, 0.0, 1.0).unwrap_err()), "sun.angular_radius");
        assert_eq!(name(SunDisk::new(Vec3::Y, f32::NAN, 1.0).unwrap_err()), "sun.angular_radius");
        // Found by the capi_calls fuzzer: a solid angle that rounds to 0 gave pdf ∞ (and NaN).
        assert_eq!(name(SunDisk::new(Vec3::Y, 1e-30, 1.0).unwrap_err()), "sun.angular_radius");
        assert!(SunDisk::new(Vec3::Y, 1e-18, 1.0).unwrap().pdf().is_finite());
        // Found by the capi_calls fuzzer: a disk far narrower than f32 directions resolve
        // drew directions outside itself (pdf 0 from the environment guide).
        let tiny = SunDisk::new(Vec3::ONE, 6e-13, 1.0).unwrap();
        let mut rng = Pcg32::new(5, 5);
        assert!((0..1000).all(|_| tiny.contains(tiny.sample(rng.next_vec2()))));
        assert_eq!(name(SunDisk::new(Vec3::Y, 0.1, -1.0).unwrap_err()), "sun.luminance");
    }
}
