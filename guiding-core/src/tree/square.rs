//! Directions ↔ the unit square by Lambert's cylindrical equal-area map, which the
//! directional quadtree subdivides: u = (z + 1)/2, v = (φ + π)/2π, and dω = 4π du dv,
//! so a density over the square divided by 4π is a density per steradian.

use core::f32::consts::PI;

use glam::{Vec2, Vec3, Vec4};

use crate::atan2::{fast_atan2, fast_atan2_x4};

/// The largest f32 below one: square coordinates stay inside [0, 1).
pub(crate) const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// Solid angle per unit of square area, sr.
pub(crate) const SQUARE_TO_SOLID_ANGLE: f32 = 4.0 * PI;

/// The square point of unit direction `d`.
#[inline]
fn direction_to_square(d: Vec3) -> Vec2 {
    let u = (d.z + 1.0) * 0.5;
    let v = fast_atan2(d.y, d.x) * (0.5 / PI) + 0.5;
    Vec2::new(u.clamp(0.0, ONE_BELOW), v.clamp(0.0, ONE_BELOW))
}

/// The unit direction of square point `p` ∈ [0, 1]².
#[inline]
pub(crate) fn square_to_direction(p: Vec2) -> Vec3 {
    let z = (2.0 * p.x - 1.0).clamp(-1.0, 1.0);
    let r = libm::sqrtf((1.0 - z * z).max(0.0));
    let (s, c) = sin_cos_pi(2.0 * p.y - 1.0);
    Vec3::new(r * c, r * s, z)
}

/// sin(πt) for t ∈ [-1/2, 1/2]: its Taylor series to t¹¹ (truncation below 1e-8).
#[inline]
fn sin_pi_half(t: f32) -> f32 {
    let x = t * PI;
    let x2 = x * x;
    let mut r = -2.505_210_8e-8;
    r = r * x2 + 2.755_731_9e-6;
    r = r * x2 - 1.984_127e-4;
    r = r * x2 + 8.333_333e-3;
    r = r * x2 - 0.166_666_67;
    r = r * x2 + 1.0;
    r * x
}

/// (sin πx, cos πx) for x ∈ [-1, 1] to within 3e-7, several times cheaper than libm's
/// `sinf` and `cosf` (the map's angle is φ = πx).
#[inline]
pub(crate) fn sin_cos_pi(x: f32) -> (f32, f32) {
    let a = x.abs();
    // sin πx = sin π(±1 − x) folds |x| > 1/2 back into [-1/2, 1/2]; cos πx = sin π(1/2 − |x|).
    let s = if a > 0.5 { sin_pi_half(1.0f32.copysign(x) - x) } else { sin_pi_half(x) };
    (s, sin_pi_half(0.5 - a))
}

/// `d` in the frame whose polar (z) axis is world axis `axis` (0, 1 or 2 for x, y, z):
/// the coordinates turned cyclically, so the frame stays right-handed.
#[inline]
fn to_axis_frame(d: Vec3, axis: u32) -> Vec3 {
    match axis {
        0 => Vec3::new(d.y, d.z, d.x),
        1 => Vec3::new(d.z, d.x, d.y),
        _ => d,
    }
}

/// The square point of world direction `d` in the square built around world `axis`: the
/// one map from a direction to a leaf's cells that sampling's pdf, records and Q share.
#[inline]
pub(crate) fn axis_square(d: Vec3, axis: u32) -> Vec2 {
    direction_to_square(to_axis_frame(d, axis))
}

/// [`axis_square`] of four directions, each in the square of its own axis, bit for bit
/// the same: the map a batch of records pays four at a time.
#[inline]
pub(crate) fn axis_squares(directions: [Vec3; 4], axes: [u32; 4]) -> [Vec2; 4] {
    // Lane i's frame is [`to_axis_frame`]'s: its x, y and z are the world components
    // after its axis, cyclically; read by index, not by a branch per lane.
    let component = |lane: usize, turn: usize| {
        let axis = axes[lane].min(2) as usize;
        let d: &[f32; 3] = directions[lane].as_ref();
        d[(axis + turn) % 3]
    };
    let lanes = |turn: usize| Vec4::new(component(0, turn), component(1, turn), component(2, turn), component(3, turn));
    let (x, y, z) = (lanes(1), lanes(2), lanes(0));
    let u = ((z + Vec4::ONE) * 0.5).clamp(Vec4::ZERO, Vec4::splat(ONE_BELOW));
    let v = (fast_atan2_x4(y, x) * (0.5 / PI) + Vec4::splat(0.5)).clamp(Vec4::ZERO, Vec4::splat(ONE_BELOW));
    [Vec2::new(u.x, v.x), Vec2::new(u.y, v.y), Vec2::new(u.z, v.z), Vec2::new(u.w, v.w)]
}

/// The world direction of `local`, given in the frame of [`to_axis_frame`].
#[inline]
pub(crate) fn from_axis_frame(local: Vec3, axis: u32) -> Vec3 {
    match axis {
        0 => Vec3::new(local.z, local.x, local.y),
        1 => Vec3::new(local.y, local.z, local.x),
        _ => local,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn sin_cos_pi_is_within_its_bound_and_axis_frames_invert() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -1.0 + 2.0 * i as f32 / 200_000.0;
            let (s, c) = sin_cos_pi(x);
            let angle = core::f64::consts::PI * x as f64;
            worst = worst.max((s as f64 - libm::sin(angle)).abs()).max((c as f64 - libm::cos(angle)).abs());
        }
        assert!(worst < 3e-7, "worst error {worst}");
        let d = Vec3::new(0.3, -0.5, 0.8);
        for axis in 0..3 {
            assert_eq!(from_axis_frame(to_axis_frame(d, axis), axis), d);
            assert_eq!(to_axis_frame(d, axis).z, d[axis as usize]);
        }
    }

    #[test]
    fn four_squares_at_once_match_one_at_a_time() {
        let mut rng = Pcg32::new(4, 6);
        for _ in 0..50_000 {
            let directions: [Vec3; 4] = core::array::from_fn(|_| square_to_direction(rng.next_vec2()));
            let axes: [u32; 4] = core::array::from_fn(|_| (rng.next_f32() * 3.0) as u32 % 3);
            let four = axis_squares(directions, axes);
            for i in 0..4 {
                let one = axis_square(directions[i], axes[i]);
                assert_eq!((four[i].x.to_bits(), four[i].y.to_bits()), (one.x.to_bits(), one.y.to_bits()));
            }
        }
        let poles = [Vec3::Z, -Vec3::Z, Vec3::X, -Vec3::Y];
        let four = axis_squares(poles, [2, 2, 0, 1]);
        for (i, d) in poles.into_iter().enumerate() {
            assert_eq!(four[i], axis_square(d, [2, 2, 0, 1][i]));
        }
    }

    #[test]
    fn the_map_round_trips() {
        let mut rng = Pcg32::new(3, 5);
        for _ in 0..100_000 {
            let p = rng.next_vec2();
            let d = square_to_direction(p);
            assert!((d.length() - 1.0).abs() < 1e-5);
            let q = direction_to_square(d);
            assert!((p - q).abs().max_element() < 2e-5 || (p.y - q.y).abs() > 0.999, "{p} -> {d} -> {q}");
        }
        for d in [Vec3::Z, -Vec3::Z, Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y] {
            let q = direction_to_square(d);
            assert!(q.x >= 0.0 && q.x < 1.0 && q.y >= 0.0 && q.y < 1.0);
        }
    }
}
