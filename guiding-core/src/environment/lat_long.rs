//! The lat-long (equirectangular) mapping of directions, as the scene format defines it:
//! d ↦ u = 0.5 + atan2(d.x, −d.z)/2π, v = acos(d.y)/π, with (0, 0) at the image's top-left
//! and the top row looking up (+y).

use core::f32::consts::PI;

use glam::{Vec2, Vec3};

/// The (u, v) in [0, 1]² of unit direction `d`. θ is taken as atan2(sin θ, cos θ) with
/// sin θ = |(x, z)|, which stays exact at the poles where acos(y) would not.
#[inline]
pub fn uv_of_direction(d: Vec3) -> Vec2 {
    Vec2::new(0.5 + libm::atan2f(d.x, -d.z) / (2.0 * PI), libm::atan2f(sin_theta(d), d.y) / PI)
}

/// sin θ of unit direction `d` (θ from +y): |(x, z)|, exact near the poles where
/// √(1 − y²) rounds to zero.
#[inline]
pub fn sin_theta(d: Vec3) -> f32 {
    libm::sqrtf(d.x * d.x + d.z * d.z)
}

/// The unit direction at (u, v). Computed in f64, so a point sampled inside a texel maps
/// back to that texel by [`uv_of_direction`] except within a few f32 steps of its border.
#[inline]
pub fn direction_of_uv(uv: Vec2) -> Vec3 {
    use core::f64::consts::PI;
    let (sin_phi, cos_phi) = libm::sincos(2.0 * PI * (uv.x as f64 - 0.5));
    let (sin_theta, cos_theta) = libm::sincos(PI * uv.y as f64);
    Vec3::new((sin_theta * sin_phi) as f32, cos_theta as f32, (-sin_theta * cos_phi) as f32)
}

/// The texel (column, row) of a `width × height` map that direction `d` falls in.
#[inline]
pub fn texel_of_direction(d: Vec3, width: usize, height: usize) -> (usize, usize) {
    let uv = uv_of_direction(d);
    let column = ((uv.x * width as f32) as usize).min(width - 1);
    let row = ((uv.y * height as f32) as usize).min(height - 1);
    (column, row)
}

/// Density per steradian of a direction drawn uniformly in (u, v) inside one texel of a
/// `width × height` map, where sin θ = `sin_theta`: dω = 2π² sin θ du dv.
#[inline]
pub fn texel_density(width: usize, height: usize, sin_theta: f32) -> f32 {
    (width * height) as f32 / (2.0 * PI * PI * sin_theta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mapping_round_trips_and_follows_the_scene_format() {
        assert!((direction_of_uv(Vec2::new(0.5, 0.0)) - Vec3::Y).length() < 1e-6);
        assert!((direction_of_uv(Vec2::new(0.5, 0.5)) - Vec3::NEG_Z).length() < 1e-6);
        assert!((direction_of_uv(Vec2::new(0.75, 0.5)) - Vec3::X).length() < 1e-6);
        for (c, r) in [(0, 0), (5, 3), (15, 7), (8, 4)] {
            let uv = Vec2::new((c as f32 + 0.5) / 16.0, (r as f32 + 0.5) / 8.0);
            assert_eq!(texel_of_direction(direction_of_uv(uv), 16, 8), (c, r));
            assert!((uv_of_direction(direction_of_uv(uv)) - uv).length() < 1e-5);
        }
    }
}
