//! Watertight ray/triangle intersection (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013).
//!
//! The ray is sheared so that it runs along +z; each triangle's edge functions are then
//! evaluated in 2-D on the same projected vertices, so a ray through an edge shared by
//! two triangles (bit-identical vertices) cannot fall between them. Edge functions that
//! round to exactly zero are recomputed in f64.

use glam::{Vec2, Vec3, Vec3A, Vec3Swizzles};

/// A ray prepared for watertight triangle tests: its shear and permuted axes, folded into
/// three row vectors so a vertex is projected by dot products instead of indexing by
/// axis (which compiles to branches). Multiplying by the rows' zeros and ones is exact,
/// so the projection is bit for bit the permuted one of the paper.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay {
    origin: Vec3A,
    /// e_kx − S_x·e_kz, e_ky − S_y·e_kz and e_kz.
    rows: [Vec3A; 3],
    /// S_z = 1 / d_kz.
    shear_z: f32,
}

/// e_kx, e_ky, e_kz for each dominant axis kz and sign of d_kz (index 2·kz + negative),
/// with kx = kz + 1 and ky = kz + 2 (mod 3), swapped for a negative d_kz so the winding
/// of the projected triangle does not depend on the ray's direction.
const AXIS_PERMUTATIONS: [[Vec3A; 3]; 6] = [
    [Vec3A::Y, Vec3A::Z, Vec3A::X],
    [Vec3A::Z, Vec3A::Y, Vec3A::X],
    [Vec3A::Z, Vec3A::X, Vec3A::Y],
    [Vec3A::X, Vec3A::Z, Vec3A::Y],
    [Vec3A::X, Vec3A::Y, Vec3A::Z],
    [Vec3A::Y, Vec3A::X, Vec3A::Z],
];

/// A hit of [`ShearedRay::intersect`]: distance and barycentrics (b1, b2) of v1 and v2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric coordinates of v1 and v2.
    pub barycentrics: Vec2,
}

impl ShearedRay {
    /// Prepares `origin + t·direction`; `direction` must be finite and non-zero.
    #[inline]
    pub fn new(origin: impl Into<Vec3A>, direction: impl Into<Vec3A>) -> Self {
        // Random directions make every choice here a coin toss for the branch predictor,
        // so the axes are picked by arithmetic on comparison bits and a table lookup.
        let d: Vec3A = direction.into();
        let a = d.abs();
        let (y_over_x, z_over_y, z_over_x) = ((a.y > a.x) as usize, (a.z > a.y) as usize, (a.z > a.x) as usize);
        // The dominant axis, ties to the lower index.
        let kz = y_over_x * (1 + z_over_y) + (1 - y_over_x) * 2 * z_over_x;
        let negative = (d.cmplt(Vec3A::ZERO).bitmask() as usize >> kz) & 1;
        let [unit_x, unit_y, unit_z] = AXIS_PERMUTATIONS[2 * kz + negative];
        // Dot products with unit axes are exact: these are d_kz, d_kx and d_ky.
        // One division per ray: the shear only has to be the same for every triangle.
        let shear_z = 1.0 / d.dot(unit_z);
        let (shear_x, shear_y) = (d.dot(unit_x) * shear_z, d.dot(unit_y) * shear_z);
        Self { origin: origin.into(), rows: [unit_x - shear_x * unit_z, unit_y - shear_y * unit_z, unit_z], shear_z }
    }

    /// The hit with `t_min < t ≤ t_max`, either side of the triangle, if any.
    #[inline]
    pub fn intersect(&self, vertices: [Vec3; 3], t_min: f32, t_max: f32) -> Option<TriangleHit> {
        self.intersect_packed(&PackedTriangle::new(vertices), t_min, t_max)
    }

    /// [`intersect`](Self::intersect) on a triangle stored by coordinate, as the adapter
    /// keeps them: the three vertices are projected at once, one SIMD lane each, with the
    /// same products and sums per vertex as the scalar formulation (so bit for bit the
    /// same answer, and still watertight: a shared vertex projects identically in every
    /// triangle holding it).
    #[inline]
    pub fn intersect_packed(&self, triangle: &PackedTriangle, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let (uvw, scaled_t, inside) = self.edge_test(triangle);
        let determinant = uvw.x + uvw.y + uvw.z;
        if !inside || determinant == 0.0 {
            return None;
        }
        let inverse = 1.0 / determinant;
        let t = scaled_t * inverse;
        if !(t > t_min && t <= t_max) {
            return None;
        }
        Some(TriangleHit { t, barycentrics: Vec2::new(uvw.y * inverse, uvw.z * inverse) })
    }

    /// Whether the ray meets the triangle at `t_min < t < t_max` (both ends open, so a
    /// shadow ray ending on an emitter is not blocked by it): the test of
    /// [`intersect_packed`](Self::intersect_packed) with t compared as t·det against the
    /// ends scaled by the determinant, so no division, as the paper's occlusion test
    /// does. A hit within an ulp or so of an end may be judged differently.
    #[inline]
    pub fn occludes_packed(&self, triangle: &PackedTriangle, t_min: f32, t_max: f32) -> bool {
        let (uvw, scaled_t, inside) = self.edge_test(triangle);
        let determinant = uvw.x + uvw.y + uvw.z;
        // t = scaled_t / det: flip both by det's sign so the comparisons need no division.
        let sign = determinant.to_bits() & 0x8000_0000;
        let (t_det, det) = (f32::from_bits(scaled_t.to_bits() ^ sign), determinant.abs());
        inside & (t_det > t_min * det) & (t_det < t_max * det) & (determinant != 0.0)
    }

    /// The edge functions (u, v, w) of the projected triangle, t·det, and whether the
    /// ray passes inside (or on) every edge: all of u, v, w of one sign or zero.
    #[inline(always)]
    fn edge_test(&self, triangle: &PackedTriangle) -> (Vec3A, f32, bool) {
        let [row_x, row_y, row_z] = self.rows;
        let o = self.origin;
        let (x, y, z) =
            (triangle.x - Vec3A::splat(o.x), triangle.y - Vec3A::splat(o.y), triangle.z - Vec3A::splat(o.z));
        // Lanes are v0, v1, v2. Each row holds one 1, one −S and one 0, so the sums are
        // exact re-orderings of the row dot products.
        let project = |row: Vec3A| x * row.x + y * row.y + z * row.z;
        let (px, py) = (project(row_x), project(row_y));
        // (u, v, w) = (c×b, a×c, b×a) in 2-D, a lane each.
        let mut uvw = px.zxy() * py.yzx() - py.zxy() * px.yzx();
        if uvw.cmpeq(Vec3A::ZERO).any() {
            let edge = |i: usize, j: usize| (px[i] as f64 * py[j] as f64 - py[i] as f64 * px[j] as f64) as f32;
            uvw = Vec3A::new(edge(2, 1), edge(0, 2), edge(1, 0));
        }
        let inside = !(uvw.cmplt(Vec3A::ZERO).any() & uvw.cmpgt(Vec3A::ZERO).any());
        let weighted = uvw * project(row_z);
        (uvw, self.shear_z * (weighted.x + weighted.y + weighted.z), inside)
    }
}

/// A triangle stored by coordinate: the x of its three vertices in one vector, then the
/// y, then the z (48 bytes, 16-byte aligned), which [`ShearedRay::intersect_packed`]
/// projects in three SIMD steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackedTriangle {
    x: Vec3A,
    y: Vec3A,
    z: Vec3A,
}

impl PackedTriangle {
    /// Packs vertices v0, v1, v2.
    pub fn new([v0, v1, v2]: [Vec3; 3]) -> Self {
        Self { x: Vec3A::new(v0.x, v1.x, v2.x), y: Vec3A::new(v0.y, v1.y, v2.y), z: Vec3A::new(v0.z, v1.z, v2.z) }
    }

    /// Vertex `i` (0, 1 or 2).
    fn vertex(&self, i: usize) -> [f64; 3] {
        [self.x[i] as f64, self.y[i] as f64, self.z[i] as f64]
    }

    /// (v1 − v0) × (v2 − v0) in f64: f32 differences are exact there, and each product
    /// of two of them too, so only the final sums round.
    fn exact_normal([a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
        let (e1, e2) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
    }

    /// The ray parameter where `origin + t·direction` meets the triangle's plane, in
    /// f64: accurate to f32 rounding however thin the triangle. The watertight test
    /// decides *whether* a ray hits, but its t comes from edge functions that lose digits
    /// on slivers (a 3.45 × 0.008 triangle in the Grey & White Room gave t 1e-4 off); this
    /// refines the one hit a closest-hit query returns. `None` for a ray in the plane.
    #[inline]
    pub fn plane_t(&self, origin: Vec3A, direction: Vec3A) -> Option<f32> {
        let [a, b, c] = [self.vertex(0), self.vertex(1), self.vertex(2)];
        let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        // The normal must be exact, not rounded to f32: its error times |v0 − o| (which
        // may be far larger than t) would swamp a small t.
        let normal = Self::exact_normal([a, b, c]);
        let origin = origin.to_array().map(f64::from);
        let direction = direction.to_array().map(f64::from);
        let denominator = dot(direction, normal);
        let t = dot([a[0] - origin[0], a[1] - origin[1], a[2] - origin[2]], normal) / denominator;
        (denominator != 0.0 && t.is_finite()).then_some(t as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_the_inside_and_reports_barycentrics() {
        let tri = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let ray = ShearedRay::new(Vec3::new(0.25, 0.5, 2.0), Vec3::NEG_Z);
        let hit = ray.intersect(tri, 0.0, f32::INFINITY).unwrap();
        assert!((hit.t - 2.0).abs() < 1e-6);
        assert!((hit.barycentrics - Vec2::new(0.25, 0.5)).length() < 1e-6);
        // From behind, and limited by t_max and t_min.
        let back = ShearedRay::new(Vec3::new(0.25, 0.5, -1.0), Vec3::Z);
        assert!(back.intersect(tri, 0.0, f32::INFINITY).is_some());
        assert!(back.intersect(tri, 0.0, 0.5).is_none());
        assert!(back.intersect(tri, 1.5, 5.0).is_none());
        let miss = ShearedRay::new(Vec3::new(0.75, 0.75, 2.0), Vec3::NEG_Z);
        assert!(miss.intersect(tri, 0.0, f32::INFINITY).is_none());
    }

    /// Uniform numbers in [−1, 1) from a small LCG seeded with `state`: this crate's tests
    /// need no random-number dependency.
    fn uniform_stream(mut state: u64) -> impl FnMut() -> f32 {
        move || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        }
    }

    /// The paper's scalar formulation: each vertex projected by row dot products.
    fn scalar_intersect(ray: &ShearedRay, [v0, v1, v2]: [Vec3; 3], t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let [row_x, row_y, row_z] = ray.rows;
        let (a, b, c) = (Vec3A::from(v0) - ray.origin, Vec3A::from(v1) - ray.origin, Vec3A::from(v2) - ray.origin);
        let project = |p: Vec3A| Vec2::new(row_x.dot(p), row_y.dot(p));
        let (pa, pb, pc) = (project(a), project(b), project(c));
        let mut u = pc.x * pb.y - pc.y * pb.x;
        let mut v = pa.x * pc.y - pa.y * pc.x;
        let mut w = pb.x * pa.y - pb.y * pa.x;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let edge = |p: Vec2, q: Vec2| (p.x as f64 * q.y as f64 - p.y as f64 * q.x as f64) as f32;
            (u, v, w) = (edge(pc, pb), edge(pa, pc), edge(pb, pa));
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let determinant = u + v + w;
        if determinant == 0.0 {
            return None;
        }
        let t = ray.shear_z * (u * row_z.dot(a) + v * row_z.dot(b) + w * row_z.dot(c)) * (1.0 / determinant);
        (t > t_min && t <= t_max).then(|| TriangleHit { t, barycentrics: Vec2::new(v, w) * (1.0 / determinant) })
    }

    #[test]
    fn the_packed_test_answers_bit_for_bit_as_the_scalar_one() {
        let mut next = uniform_stream(0x2545_f491_4f6c_dd1d);
        let mut hits = 0;
        for i in 0..100_000 {
            let mut point = || Vec3::new(next(), next(), next());
            let triangle = [point(), point(), point()];
            // Some rays aimed at a vertex or an edge midpoint, where the edge functions vanish.
            let origin = point() * 3.0;
            let aim = match i % 3 {
                0 => point() * 0.5,
                1 => triangle[0],
                _ => triangle[1].lerp(triangle[2], 0.5),
            };
            let Some(direction) = (aim - origin).try_normalize() else { continue };
            let ray = ShearedRay::new(origin, direction);
            let packed = ray.intersect(triangle, 0.0, f32::INFINITY);
            let scalar = scalar_intersect(&ray, triangle, 0.0, f32::INFINITY);
            let bits = |h: Option<TriangleHit>| {
                h.map(|h| (h.t.to_bits(), h.barycentrics.x.to_bits(), h.barycentrics.y.to_bits()))
            };
            assert_eq!(bits(packed), bits(scalar), "case {i}");
            hits += packed.is_some() as u32;
        }
        assert!(hits > 30_000, "{hits} hits");
    }

    /// The paper's axis choice, by indexing: kz the largest |d| (ties to the lower axis),
    /// kx and ky the next two, swapped when d_kz < 0.
    fn paper_shear(origin: Vec3, direction: Vec3) -> ShearedRay {
        let kz = direction.abs().max_position();
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if direction[kz] < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        let shear_z = 1.0 / direction[kz];
        let (shear_x, shear_y) = (direction[kx] * shear_z, direction[ky] * shear_z);
        let unit = |k: usize| Vec3A::from(Vec3::AXES[k]);
        ShearedRay {
            origin: origin.into(),
            rows: [unit(kx) - shear_x * unit(kz), unit(ky) - shear_y * unit(kz), unit(kz)],
            shear_z,
        }
    }

    #[test]
    fn the_branch_free_shear_is_the_papers() {
        let bits = |r: &ShearedRay| {
            let lanes = |v: Vec3A| v.to_array().map(f32::to_bits);
            (lanes(r.origin), r.rows.map(lanes), r.shear_z.to_bits())
        };
        let mut next = uniform_stream(0x9e37_79b9_7f4a_7c15);
        let mut directions: Vec<Vec3> = (0..10_000).map(|_| Vec3::new(next(), next(), next())).collect();
        // Ties between axes, zeros of either sign, and each axis alone, both ways.
        for d in [Vec3::ONE, Vec3::new(-1.0, 1.0, 0.5), Vec3::new(0.5, -1.0, -1.0), Vec3::new(-0.0, 0.0, -1.0)] {
            directions.push(d);
        }
        for axis in Vec3::AXES {
            directions.extend([axis, -axis]);
        }
        for d in directions.into_iter().filter(|d| *d != Vec3::ZERO) {
            let origin = Vec3::new(0.25, -3.0, 7.5);
            assert_eq!(bits(&ShearedRay::new(origin, d)), bits(&paper_shear(origin, d)), "direction {d}");
        }
    }

    #[test]
    fn occlusion_agrees_with_the_closest_hit_test_inside_the_segment() {
        let mut next = uniform_stream(0x2545_f491_4f6c_dd1d);
        let mut blocked = 0;
        for i in 0..100_000 {
            let mut point = || Vec3::new(next(), next(), next());
            let triangle = PackedTriangle::new([point(), point(), point()]);
            let origin = point() * 3.0;
            let Some(direction) = (point() * 0.5 - origin).try_normalize() else { continue };
            let ray = ShearedRay::new(origin, direction);
            let (t_min, t_max) = (0.5 * (next() + 1.0), 1.0 + 4.0 * (next() + 1.0));
            let hit = ray.intersect_packed(&triangle, t_min, t_max);
            let occludes = ray.occludes_packed(&triangle, t_min, t_max);
            // The two may differ only for a hit within rounding of an end of the segment.
            let near_an_end = |t: f32| (t - t_min).abs() <= 1e-5 * t || (t - t_max).abs() <= 1e-5 * t;
            match hit {
                Some(hit) if !near_an_end(hit.t) => assert_eq!(occludes, hit.t < t_max, "case {i}"),
                None => {
                    let unbounded = ray.intersect_packed(&triangle, f32::NEG_INFINITY, f32::INFINITY);
                    if !unbounded.is_some_and(|h| near_an_end(h.t)) {
                        assert!(!occludes, "case {i}");
                    }
                }
                Some(_) => {}
            }
            blocked += occludes as u32;
        }
        assert!(blocked > 5_000, "{blocked} blocked");
        // The far end is open: a segment ending exactly on the triangle is not blocked.
        let floor =
            PackedTriangle::new([Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0)]);
        let down = ShearedRay::new(Vec3::Y, Vec3::NEG_Y);
        assert!(down.occludes_packed(&floor, 0.0, 1.5));
        assert!(!down.occludes_packed(&floor, 0.0, 1.0));
        assert!(!down.occludes_packed(&floor, 1.0, 2.0));
        assert!(down.occludes_packed(&floor, 0.0, f32::INFINITY));
    }

    #[test]
    fn the_plane_distance_stays_exact_on_a_sliver() {
        // A 3.45 × 0.008 triangle of the Grey & White Room and a ray Embree and obvhs
        // disagreed on: the exact t (f64 from these f32 inputs) is 0.109698336.
        let sliver = [
            Vec3::new(0.089458, 2.824222, -0.089458),
            Vec3::new(0.089458, 2.824222, -3.543342),
            Vec3::new(0.093327, 2.831541, -3.539473),
        ];
        let origin = Vec3::new(0.135_394_63, 2.759_409_7, -1.925_373_1);
        let direction = Vec3::new(-0.411_418_86, 0.604_699_13, 0.681_963);
        let exact = 0.109_698_336_f64;
        let watertight = ShearedRay::new(origin, direction).intersect(sliver, 0.0, f32::INFINITY).unwrap();
        let plane = PackedTriangle::new(sliver).plane_t(origin.into(), direction.into()).unwrap();
        assert!(((plane as f64 - exact) / exact).abs() < 1e-6, "{plane}");
        // What the refinement is for: the edge functions' t is far off here.
        assert!(((watertight.t as f64 - exact) / exact).abs() > 1e-5, "{}", watertight.t);
        // Parallel to the plane: no distance.
        assert_eq!(PackedTriangle::new([Vec3::ZERO, Vec3::X, Vec3::Z]).plane_t(Vec3A::ZERO, Vec3A::Z), None);
        // A degenerate triangle has no plane.
        assert_eq!(PackedTriangle::new([Vec3::ONE; 3]).plane_t(Vec3A::ZERO, Vec3A::Z), None);
    }

    #[test]
    fn a_shared_edge_is_never_missed() {
        // Two triangles sharing the diagonal of a unit square; rays exactly along it.
        let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
        for i in 0..=1000 {
            let s = i as f32 / 1000.0;
            let target = a.lerp(c, s);
            let origin = target + Vec3::new(0.3, -0.7, 1.9);
            let ray = ShearedRay::new(origin, (target - origin).normalize());
            let hits = [ray.intersect([a, b, c], 0.0, f32::INFINITY), ray.intersect([a, c, d], 0.0, f32::INFINITY)];
            assert!(hits.iter().any(Option::is_some), "gap at s = {s}");
        }
    }
}
