//! Low-discrepancy point sets and a small random number generator.

use glam::Vec2;

/// The base-2 radical inverse (van der Corput) of `index`, in [0, 1).
pub fn radical_inverse_base2(index: u32) -> f32 {
    // 24 significant bits: a value that rounds to 1.0 is impossible.
    (index.reverse_bits() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Point `index` of the `count`-point Hammersley set: ((index + ½)/count, radical inverse).
///
/// The first coordinate is stratified into `count` equal intervals, which is what makes
/// area-proportional placement exact: every triangle receives its share of points up to
/// one.
pub fn hammersley(index: u32, count: u32) -> Vec2 {
    Vec2::new(((index as f64 + 0.5) / count as f64) as f32, radical_inverse_base2(index))
}

/// PCG32 (O'Neill 2014): a small, fast, seedable generator for tests, validation and
/// renderers that have none of their own.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    increment: u64,
}

impl Pcg32 {
    /// A generator for `seed` on stream `stream`; different streams are independent.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Self { state: 0, increment: (stream << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// 32 uniformly distributed bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.increment);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// A uniform number in [0, 1) with 24 random bits.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Two uniform numbers in [0, 1).
    pub fn next_vec2(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radical_inverse_of_small_indices() {
        assert_eq!(radical_inverse_base2(0), 0.0);
        assert_eq!(radical_inverse_base2(1), 0.5);
        assert_eq!(radical_inverse_base2(2), 0.25);
        assert_eq!(radical_inverse_base2(3), 0.75);
        assert!(radical_inverse_base2(u32::MAX) < 1.0);
    }

    #[test]
    fn hammersley_first_coordinate_is_stratified() {
        let n = 100;
        for i in 0..n {
            let p = hammersley(i, n);
            assert!(p.x >= i as f32 / n as f32 && p.x < (i + 1) as f32 / n as f32);
        }
    }

    #[test]
    fn pcg_is_uniform_enough_and_deterministic() {
        let mut a = Pcg32::new(7, 3);
        let mut b = Pcg32::new(7, 3);
        let mut mean = 0.0f64;
        for _ in 0..100_000 {
            let x = a.next_f32();
            assert_eq!(x, b.next_f32());
            assert!((0.0..1.0).contains(&x));
            mean += x as f64;
        }
        mean /= 100_000.0;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
        assert_ne!(Pcg32::new(7, 4).next_u32(), Pcg32::new(7, 3).next_u32());
    }
}
