//! [`BoxLanes`]: eight boxes side by side (one array per coordinate), so that a ray's
//! spans in all of them are computed together and the compiler can use vector lanes;
//! and the box geometry around them: a ray's span in one box, the runs a ray crosses,
//! the Morton order that makes a run a compact cluster.

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

    /// Per box: density · ∫ t² dt over the ray's span, (t1³ − t0³)/3 (0 where it misses).
    #[inline]
    pub(super) fn span_terms(&self, origin: Vec3, inverse_direction: Vec3) -> [f32; LANES] {
        let (near, far) = self.spans(origin, inverse_direction);
        let mut terms = [0.0f32; LANES];
        for i in 0..LANES {
            let (t0, t1) = (near[i], far[i]);
            let cube = self.density[i] * (t1 * t1 * t1 - t0 * t0 * t0) * (1.0 / 3.0);
            terms[i] = if t1 > t0 { cube } else { 0.0 };
        }
        terms
    }

    /// Σ over the boxes of density · ∫ t² dt over the ray's span.
    #[inline]
    pub(super) fn span_integral(&self, origin: Vec3, inverse_direction: Vec3) -> f32 {
        sum_lanes(self.span_terms(origin, inverse_direction))
    }

    /// As [`span_integral`](Self::span_integral), each box's density scaled by `scale`.
    #[inline]
    pub(super) fn span_integral_scaled(&self, origin: Vec3, inverse_direction: Vec3, scale: &[f32; LANES]) -> f32 {
        let terms = self.span_terms(origin, inverse_direction);
        sum_lanes(core::array::from_fn(|i| terms[i] * scale[i]))
    }
}

/// The lanes' sum, pairwise, so they add as vectors.
#[inline]
fn sum_lanes(terms: [f32; LANES]) -> f32 {
    let half: [f32; 4] = core::array::from_fn(|i| terms[i] + terms[i + 4]);
    (half[0] + half[2]) + (half[1] + half[3])
}

/// The parameters `[t0, t1]` of the ray `origin + t·direction` inside the box, with
/// `1/direction` given; empty (t0 ≥ t1) when it misses. Infinite reciprocals of zero
/// components work: such a ray is inside the slab or never.
pub(crate) fn ray_box(origin: Vec3, inverse_direction: Vec3, low: Vec3, high: Vec3) -> (f32, f32) {
    let a = (low - origin) * inverse_direction;
    let b = (high - origin) * inverse_direction;
    // A NaN (0·∞: the origin on a slab's plane with the ray along it) must not win:
    // f32::min/max return the other operand.
    let near = a.min(b);
    let far = a.max(b);
    (near.x.max(near.y).max(near.z), far.x.min(far.y).min(far.z))
}

/// The Morton code (10 bits per axis, interleaved) of `p` in the unit cube.
pub(super) fn morton(p: Vec3) -> u32 {
    let spread = |v: f32| {
        let mut x = ((v.clamp(0.0, 1.0) * 1023.0) as u32) & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    spread(p.x) | (spread(p.y) << 1) | (spread(p.z) << 2)
}

/// Calls `visit` with the index of every run of [`LANES`] boxes whose bounds the ray
/// `origin + t·direction` (`1/direction` given) crosses; `run_lanes` holds the runs'
/// bounds, [`LANES`] runs to an entry.
#[inline]
pub(super) fn crossed_runs(
    run_lanes: &[BoxLanes],
    origin: Vec3,
    inverse_direction: Vec3,
    mut visit: impl FnMut(usize),
) {
    for (group, runs) in run_lanes.iter().enumerate() {
        let mut hit = runs.hits(origin, inverse_direction);
        while hit != 0 {
            visit(group * LANES + hit.trailing_zeros() as usize);
            hit &= hit - 1;
        }
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
