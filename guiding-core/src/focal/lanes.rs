//! [`BoxLanes`]: eight boxes side by side (one array per coordinate), so that a ray's
//! spans in all of them are computed together and the compiler can use vector lanes.

use glam::Vec3;

/// Boxes per [`BoxLanes`].
pub(super) const LANES: usize = 8;

/// Eight axis-aligned boxes, each with a density; unused lanes have density 0 and count
/// for nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BoxLanes {
    low: [[f32; LANES]; 3],
    high: [[f32; LANES]; 3],
    density: [f32; LANES],
}

impl BoxLanes {
    /// Up to [`LANES`] boxes `(low, high, density)`; the lanes left over repeat the first
    /// box with density 0 (finite spans, no weight).
    pub(super) fn new(boxes: &[(Vec3, Vec3, f32)]) -> Self {
        debug_assert!(!boxes.is_empty() && boxes.len() <= LANES);
        let mut lanes = Self { low: [[0.0; LANES]; 3], high: [[0.0; LANES]; 3], density: [0.0; LANES] };
        for i in 0..LANES {
            let (low, high, density) = boxes.get(i).copied().unwrap_or((boxes[0].0, boxes[0].1, 0.0));
            for axis in 0..3 {
                lanes.low[axis][i] = low[axis];
                lanes.high[axis][i] = high[axis];
            }
            lanes.density[i] = density;
        }
        lanes
    }

    /// The span `[t0, t1]` (t0 ≥ 0) of the ray `origin + t·direction` in each box, with
    /// `1/direction` given; empty (t1 ≤ t0) where it misses. A NaN slab (0·∞: the origin
    /// on a slab's plane, the ray along it) is skipped, as f32::min/max skip NaN.
    #[inline]
    fn spans(&self, origin: Vec3, inverse_direction: Vec3) -> ([f32; LANES], [f32; LANES]) {
        let mut near = [0.0f32; LANES];
        let mut far = [f32::INFINITY; LANES];
        for axis in 0..3 {
            let (o, inv) = (origin[axis], inverse_direction[axis]);
            for i in 0..LANES {
                let a = (self.low[axis][i] - o) * inv;
                let b = (self.high[axis][i] - o) * inv;
                // Comparisons, not f32::min/max: each is one vector instruction (minps,
                // maxps), where f32's NaN rules cost a compare and a blend more. A NaN
                // slab compares false everywhere and leaves near and far as they were.
                let (entry, exit) = if a < b { (a, b) } else { (b, a) };
                near[i] = if entry > near[i] { entry } else { near[i] };
                far[i] = if exit < far[i] { exit } else { far[i] };
            }
        }
        (near, far)
    }

    /// Bit i set where the ray's span in box i is not empty and its density is not 0.
    #[inline]
    pub(super) fn hits(&self, origin: Vec3, inverse_direction: Vec3) -> u32 {
        let (near, far) = self.spans(origin, inverse_direction);
        (0..LANES).fold(0, |mask, i| mask | (((far[i] > near[i] && self.density[i] > 0.0) as u32) << i))
    }

    /// Σ over the boxes of density · ∫ t² dt over the ray's span: (t1³ − t0³)/3.
    #[inline]
    pub(super) fn span_integral(&self, origin: Vec3, inverse_direction: Vec3) -> f32 {
        let (near, far) = self.spans(origin, inverse_direction);
        let mut terms = [0.0f32; LANES];
        for i in 0..LANES {
            let (t0, t1) = (near[i], far[i]);
            let cube = self.density[i] * (t1 * t1 * t1 - t0 * t0 * t0);
            terms[i] = if t1 > t0 { cube } else { 0.0 };
        }
        // Pairwise, so the lanes add as vectors.
        let half: [f32; 4] = core::array::from_fn(|i| terms[i] + terms[i + 4]);
        ((half[0] + half[2]) + (half[1] + half[3])) * (1.0 / 3.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_match_the_box_one_at_a_time_and_padding_counts_for_nothing() {
        let unit = (Vec3::ZERO, Vec3::ONE, 2.0);
        let shifted = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 1.0, 1.0), 0.5);
        let lanes = BoxLanes::new(&[unit, shifted]);
        let origin = Vec3::new(-1.0, 0.5, 0.5);
        let inverse = Vec3::X.recip();
        // Through both boxes along x: [1, 2] in the first, [3, 4] in the second.
        let expected = 2.0 * (8.0 - 1.0) / 3.0 + 0.5 * (64.0 - 27.0) / 3.0;
        assert!((lanes.span_integral(origin, inverse) - expected).abs() < 1e-5);
        assert_eq!(lanes.hits(origin, inverse), 0b11);
        // From inside the first box, its span starts at 0.
        let inside = Vec3::splat(0.5);
        assert!(
            (lanes.span_integral(inside, inverse)
                - (2.0 * 0.125 / 3.0 + 0.5 * (2.5f32.powi(3) - 1.5f32.powi(3)) / 3.0))
                .abs()
                < 1e-5
        );
        // Away from both: nothing; along a slab's plane (NaN slab): still finite.
        assert_eq!(lanes.hits(origin, (-Vec3::X).recip()), 0);
        assert_eq!(lanes.span_integral(origin, (-Vec3::X).recip()), 0.0);
        let on_plane = Vec3::new(-1.0, 0.0, 0.5);
        assert!(lanes.span_integral(on_plane, inverse).is_finite());
    }
}
