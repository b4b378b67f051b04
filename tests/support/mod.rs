//! Shared pieces of the workspace tests: small scenes and the table access the generic
//! guide harness needs.
#![allow(dead_code)]

use glam::{Vec2, Vec3};
use guiding_core::{
    DirectionSample, DirectionalDistribution, Frame, Guide, HemisphereGrid, HemisphereGridSettings, HemisphereMapping,
    PatchLayout, ProbeId, Triangle, UpdateRule,
};

/// Which way a box's faces look.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Winding {
    /// Front faces point into the box (a room).
    Inward,
    /// Front faces point out of the box (a solid).
    Outward,
}

/// The 12 triangles of the axis-aligned box `min`–`max`.
pub fn box_triangles(min: Vec3, max: Vec3, winding: Winding) -> Vec<Triangle> {
    let corner = |i: u32| Vec3::select(glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), max, min);
    // Quads wound counter-clockwise seen from outside.
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3]];
    quads
        .iter()
        .flat_map(|q| {
            let [a, b, c, d] = q.map(corner);
            match winding {
                Winding::Outward => [Triangle::new(a, b, c), Triangle::new(a, c, d)],
                Winding::Inward => [Triangle::new(a, c, b), Triangle::new(a, d, c)],
            }
        })
        .collect()
}

/// The six inward-facing walls of the box [-1, 1]³.
pub fn box_walls() -> Vec<Triangle> {
    box_triangles(Vec3::NEG_ONE, Vec3::ONE, Winding::Inward)
}

/// What the generic harness needs from a guide beyond the [`Guide`] trait: regions to
/// test and direct access to their tables.
pub trait TableAccess: Guide {
    /// A few surface points (position, normal) spread over the scene.
    fn test_points(&self) -> Vec<(Vec3, Vec3)>;
    /// The regions of [`test_points`](Self::test_points), with their normals.
    fn test_regions(&self) -> Vec<(Self::Region, Vec3)> {
        self.test_points()
            .into_iter()
            .map(|(p, n)| (self.locate(p, n).expect("the test points carry regions"), n))
            .collect()
    }
    /// Entries per region.
    fn entry_count(&self) -> usize;
    /// Overwrites a region's Q table (one value per entry).
    fn set_entries(&mut self, region: Self::Region, values: &[f32]);
    /// Q of the entry that holds `direction`.
    fn entry_value(&self, region: Self::Region, direction: Vec3) -> f32;
    /// Every Q of every region.
    fn all_values(&self) -> Vec<f32>;
    /// The floor no Q may go under.
    fn floor(&self) -> f32;
}

/// A 96-probe hemisphere grid over [`box_walls`] with the given mapping and rule.
pub fn hemisphere_grid(mapping: HemisphereMapping, rule: UpdateRule) -> HemisphereGrid {
    let settings = HemisphereGridSettings {
        probe_count: Some(96),
        layout: PatchLayout { mapping, ..Default::default() },
        update_rule: rule,
        ..Default::default()
    };
    HemisphereGrid::build(&box_walls(), settings).expect("grid over the box")
}

impl TableAccess for HemisphereGrid {
    fn test_points(&self) -> Vec<(Vec3, Vec3)> {
        // The floor, a wall and the ceiling of the box, each with its inward normal.
        vec![
            (Vec3::new(0.1, -1.0, 0.2), Vec3::Y),
            (Vec3::new(-1.0, 0.3, -0.4), Vec3::X),
            (Vec3::new(0.5, 1.0, 0.5), -Vec3::Y),
        ]
    }

    fn entry_count(&self) -> usize {
        self.patch_count()
    }

    fn set_entries(&mut self, region: ProbeId, values: &[f32]) {
        self.set_q_values(region, values);
    }

    fn entry_value(&self, region: ProbeId, direction: Vec3) -> f32 {
        let local = Frame::from_normal(self.probe_normals()[region.0 as usize]).to_local(direction);
        let patch = self.settings().layout.patch_of(local).expect("direction in the probe's hemisphere");
        self.q(region, patch)
    }

    fn all_values(&self) -> Vec<f32> {
        self.q_values().iter().map(|q| f32::from_bits(q.load(std::sync::atomic::Ordering::Relaxed))).collect()
    }

    fn floor(&self) -> f32 {
        self.settings().q_floor
    }
}

/// A distribution that samples like `inner` but reports the pdf of `inner` rotated by
/// `angle` about `axis`: a deliberately wrong pdf that still integrates to one.
pub struct RotatedPdf<D> {
    pub inner: D,
    pub frame: Frame,
    pub angle: f32,
}

impl<D: DirectionalDistribution> RotatedPdf<D> {
    fn rotated(&self, d: Vec3) -> Vec3 {
        let local = self.frame.to_local(d);
        let (s, c) = self.angle.sin_cos();
        self.frame.to_world(Vec3::new(c * local.x - s * local.y, s * local.x + c * local.y, local.z))
    }
}

impl<D: DirectionalDistribution> DirectionalDistribution for RotatedPdf<D> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let s = self.inner.sample(u);
        DirectionSample { direction: s.direction, pdf: self.pdf(s.direction) }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        self.inner.pdf(self.rotated(direction))
    }
}
