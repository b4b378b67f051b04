//! A fast atan2 with a bounded error, for mapping directions to the cells of the
//! directional structures.

use core::f32::consts::{FRAC_PI_2, PI};

use glam::Vec4;

/// atan2(y, x) in [-π, π] to within 2e-6 rad: an odd minimax polynomial for atan on
/// [0, 1] and the octant identities, several times cheaper than libm's. The structures
/// use it where a direction is mapped to its cell (pdf and records); sampling goes cell →
/// direction by sine and cosine, so the two disagree only for directions within 2e-6 rad
/// of a cell's edge.
#[inline]
pub(crate) fn fast_atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if large == 0.0 {
        return 0.0;
    }
    let a = small / large;
    let s = a * a;
    let mut r = -0.011_721_2;
    r = r * s + 0.052_653_32;
    r = r * s - 0.116_432_87;
    r = r * s + 0.193_543_46;
    r = r * s - 0.332_623_47;
    r = r * s + 0.999_977_26;
    r *= a;
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// [`fast_atan2`] of four pairs at once, bit for bit the same: the same operations in
/// the same order, with selects for its branches. For maps done in batches (the tree's
/// records), where four lanes cost about what one does.
#[inline]
pub(crate) fn fast_atan2_x4(y: Vec4, x: Vec4) -> Vec4 {
    let (ax, ay) = (x.abs(), y.abs());
    let steep = ay.cmpgt(ax);
    let (small, large) = (Vec4::select(steep, ax, ay), Vec4::select(steep, ay, ax));
    let a = small / large;
    let s = a * a;
    let mut r = Vec4::splat(-0.011_721_2);
    r = r * s + Vec4::splat(0.052_653_32);
    r = r * s - Vec4::splat(0.116_432_87);
    r = r * s + Vec4::splat(0.193_543_46);
    r = r * s - Vec4::splat(0.332_623_47);
    r = r * s + Vec4::splat(0.999_977_26);
    r *= a;
    r = Vec4::select(steep, Vec4::splat(FRAC_PI_2) - r, r);
    r = Vec4::select(x.cmplt(Vec4::ZERO), Vec4::splat(PI) - r, r);
    r = Vec4::select(y.cmplt(Vec4::ZERO), -r, r);
    // 0/0 above gave NaN where both are zero; the scalar one returns 0 there first.
    Vec4::select(large.cmpeq(Vec4::ZERO), Vec4::ZERO, r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn fast_atan2_is_within_its_bound() {
        let mut rng = Pcg32::new(8, 8);
        let mut worst = 0.0f64;
        for _ in 0..1_000_000 {
            let (x, y) = (rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0);
            let exact = libm::atan2(y as f64, x as f64);
            worst = worst.max((fast_atan2(y, x) as f64 - exact).abs());
        }
        assert!(worst < 2e-6, "worst error {worst}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert!((fast_atan2(1.0, 0.0) - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((fast_atan2(0.0, -1.0) - PI).abs() < 1e-6);
    }

    #[test]
    fn four_at_once_match_one_at_a_time_bit_for_bit() {
        let mut rng = Pcg32::new(9, 2);
        let special = [0.0, -0.0, 1.0, -1.0, 1e-30, -1e-30, 0.5, -0.5];
        for i in 0..250_000 {
            let mut pair = || {
                if i % 7 == 0 {
                    special[(rng.next_f32() * 8.0) as usize % 8]
                } else {
                    rng.next_f32() * 2.0 - 1.0
                }
            };
            let (y, x) = (
                Vec4::from_array(core::array::from_fn(|_| pair())),
                Vec4::from_array(core::array::from_fn(|_| pair())),
            );
            let four = fast_atan2_x4(y, x);
            for lane in 0..4 {
                assert_eq!(
                    four[lane].to_bits(),
                    fast_atan2(y[lane], x[lane]).to_bits(),
                    "atan2({}, {})",
                    y[lane],
                    x[lane]
                );
            }
        }
    }
}
