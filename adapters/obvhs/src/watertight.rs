//! Watertight ray/triangle intersection (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013).
//!
//! The ray is sheared so that it runs along +z; each triangle's edge functions are then
//! evaluated in 2-D on the same projected vertices, so a ray through an edge shared by
//! two triangles (bit-identical vertices) cannot fall between them. Edge functions that
//! round to exactly zero are recomputed in f64.

use glam::{Vec2, Vec3, Vec3A};

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
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        let kz = direction.abs().max_position();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding of the projected triangle independent of the ray's direction.
        if direction[kz] < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        let (shear_x, shear_y) = (direction[kx] / direction[kz], direction[ky] / direction[kz]);
        let unit = |k: usize| Vec3A::from(Vec3::AXES[k]);
        Self {
            origin: origin.into(),
            rows: [unit(kx) - shear_x * unit(kz), unit(ky) - shear_y * unit(kz), unit(kz)],
            shear_z: 1.0 / direction[kz],
        }
    }

    /// The hit with `t_min < t ≤ t_max`, either side of the triangle, if any.
    #[inline]
    pub fn intersect(&self, [v0, v1, v2]: [Vec3; 3], t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let [row_x, row_y, row_z] = self.rows;
        let (a, b, c) = (Vec3A::from(v0) - self.origin, Vec3A::from(v1) - self.origin, Vec3A::from(v2) - self.origin);
        let project = |p: Vec3A| Vec2::new(row_x.dot(p), row_y.dot(p));
        let (pa, pb, pc) = (project(a), project(b), project(c));
        let mut u = pc.x * pb.y - pc.y * pb.x;
        let mut v = pa.x * pc.y - pa.y * pc.x;
        let mut w = pb.x * pa.y - pb.y * pa.x;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let edge = |p: Vec2, q: Vec2| (p.x as f64 * q.y as f64 - p.y as f64 * q.x as f64) as f32;
            u = edge(pc, pb);
            v = edge(pa, pc);
            w = edge(pb, pa);
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let determinant = u + v + w;
        if determinant == 0.0 {
            return None;
        }
        let scaled_t = self.shear_z * (u * row_z.dot(a) + v * row_z.dot(b) + w * row_z.dot(c));
        let inverse = 1.0 / determinant;
        let t = scaled_t * inverse;
        if !(t > t_min && t <= t_max) {
            return None;
        }
        Some(TriangleHit { t, barycentrics: Vec2::new(v * inverse, w * inverse) })
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
