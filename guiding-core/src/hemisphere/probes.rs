//! Probe points on the scene's surfaces: where hemispheres of Q are stored.

use alloc::vec::Vec;
use glam::{Vec2, Vec3};

use crate::error::Error;
use crate::geometry::{square_to_triangle_barycentrics, Triangle};
use crate::low_discrepancy::radical_inverse_base2;

/// Probe positions (scene units) and unit normals, plus the typical distance between
/// neighbouring probes, which sizes the lookup grid.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeSet {
    /// Probe positions, scene units.
    pub positions: Vec<Vec3>,
    /// Unit normals: each probe's hemisphere is the side its normal points to.
    pub normals: Vec<Vec3>,
    /// Typical distance between neighbouring probes, scene units.
    pub spacing: f32,
}

impl ProbeSet {
    /// `count` probes at the points of a 2-D Hammersley set mapped onto `triangles` in
    /// proportion to their area: the first coordinate, stratified into `count` equal
    /// intervals, picks a triangle by inverting the area CDF and is then rescaled to pick
    /// the point inside it together with the second (radical inverse) coordinate. Each
    /// triangle gets its area's share of probes, up to one.
    ///
    /// With `two_sided`, each point carries two probes, one per side (count/2 points; a
    /// count of 1 gives one front-facing probe). Degenerate triangles get no probes; a
    /// NaN or infinite coordinate is an error.
    pub fn place_on_triangles(triangles: &[Triangle], count: usize, two_sided: bool) -> Result<Self, Error> {
        if let Some(index) = triangles.iter().position(|t| !t.is_finite()) {
            return Err(Error::NonFiniteTriangle { index });
        }
        let mut cumulative_area = Vec::with_capacity(triangles.len());
        let mut total_area = 0.0f64;
        for triangle in triangles {
            let area = triangle.area() as f64;
            if area.is_finite() {
                total_area += area;
            }
            cumulative_area.push(total_area);
        }
        if total_area <= 0.0 || count == 0 {
            return Err(Error::NoSurface);
        }
        let points = if two_sided && count >= 2 { count / 2 } else { count };
        let probes_per_point = if two_sided && count >= 2 { 2 } else { 1 };
        let mut positions = Vec::with_capacity(points * probes_per_point);
        let mut normals = Vec::with_capacity(points * probes_per_point);
        for i in 0..points {
            let target = (i as f64 + 0.5) / points as f64 * total_area;
            let index = cumulative_area.partition_point(|&c| c <= target).min(triangles.len() - 1);
            let start = if index == 0 { 0.0 } else { cumulative_area[index - 1] };
            let area = cumulative_area[index] - start;
            let Some(normal) = triangles[index].normal() else {
                // Only reachable through rounding at a zero-area triangle's CDF step.
                continue;
            };
            let u = (((target - start) / area) as f32).clamp(0.0, 1.0);
            let barycentrics = square_to_triangle_barycentrics(Vec2::new(u, radical_inverse_base2(i as u32)));
            let position = triangles[index].point(barycentrics);
            positions.push(position);
            normals.push(normal);
            if probes_per_point == 2 {
                positions.push(position);
                normals.push(-normal);
            }
        }
        if positions.is_empty() {
            return Err(Error::NoSurface);
        }
        let spacing = libm::sqrt(total_area / points as f64) as f32;
        Ok(Self { positions, normals, spacing })
    }

    /// Probes at points the caller chose (e.g. first hits of camera rays). The spacing is
    /// estimated from the bounding box: its surface area shared among the probes.
    pub fn from_points(positions: Vec<Vec3>, normals: Vec<Vec3>) -> Self {
        let (min, max) = positions
            .iter()
            .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let extent = (max - min).max(Vec3::ZERO);
        let box_area = 2.0 * (extent.x * extent.y + extent.y * extent.z + extent.z * extent.x);
        let spacing = libm::sqrtf(box_area / positions.len().max(1) as f32);
        Self { positions, normals, spacing }
    }

    /// Number of probes.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no probes.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_square(z: f32, scale: f32) -> [Triangle; 2] {
        let p = |x: f32, y: f32| Vec3::new(x * scale, y * scale, z);
        [Triangle::new(p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)), Triangle::new(p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0))]
    }

    #[test]
    fn probes_follow_area() {
        // One square of area 1 and one of area 9: 10% and 90% of the probes.
        let mut triangles = unit_square(0.0, 1.0).to_vec();
        triangles.extend(unit_square(5.0, 3.0));
        let probes = ProbeSet::place_on_triangles(&triangles, 1000, false).unwrap();
        assert_eq!(probes.len(), 1000);
        let on_small = probes.positions.iter().filter(|p| p.z == 0.0).count();
        assert!((99..=101).contains(&on_small), "{on_small}");
        for (p, n) in probes.positions.iter().zip(&probes.normals) {
            assert_eq!(*n, Vec3::Z);
            let side = if p.z == 0.0 { 1.0 } else { 3.0 };
            assert!(p.x >= 0.0 && p.x <= side && p.y >= 0.0 && p.y <= side);
        }
        assert!((probes.spacing - libm::sqrtf(10.0 / 1000.0)).abs() < 1e-5);
    }

    #[test]
    fn probes_cover_a_square_evenly() {
        // Each of the 4×4 sub-squares of the unit square gets its 1/16 share, ± a few.
        let probes = ProbeSet::place_on_triangles(&unit_square(0.0, 1.0), 1600, false).unwrap();
        let mut counts = [0u32; 16];
        for p in &probes.positions {
            let cell = ((p.x * 4.0) as usize).min(3) * 4 + ((p.y * 4.0) as usize).min(3);
            counts[cell] += 1;
        }
        assert!(counts.iter().all(|&c| (80..=120).contains(&c)), "{counts:?}");
    }

    #[test]
    fn two_sided_probes_come_in_pairs() {
        let probes = ProbeSet::place_on_triangles(&unit_square(0.0, 1.0), 10, true).unwrap();
        assert_eq!(probes.len(), 10);
        for pair in probes.normals.chunks(2) {
            assert_eq!(pair[0], -pair[1]);
        }
        let single = ProbeSet::place_on_triangles(&unit_square(0.0, 1.0), 1, true).unwrap();
        assert_eq!(single.len(), 1);
    }

    #[test]
    fn bad_triangles_are_reported() {
        let degenerate = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X)];
        assert_eq!(ProbeSet::place_on_triangles(&degenerate, 4, false), Err(Error::NoSurface));
        let mut with_nan = unit_square(0.0, 1.0).to_vec();
        with_nan.push(Triangle::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Y));
        assert_eq!(ProbeSet::place_on_triangles(&with_nan, 4, false), Err(Error::NonFiniteTriangle { index: 2 }));
        // Degenerate triangles among good ones simply get no probes.
        let mut mixed = degenerate.to_vec();
        mixed.extend(unit_square(0.0, 1.0));
        let probes = ProbeSet::place_on_triangles(&mixed, 50, false).unwrap();
        assert!(probes.normals.iter().all(|&n| n == Vec3::Z));
    }
}
