//! # guiding-obvhs
//!
//! Lodestar's [`Intersector`] over [obvhs](https://crates.io/crates/obvhs) bounding
//! volume hierarchies, pure Rust, and watertight: a ray through an edge or vertex shared
//! by triangles of a closed mesh never slips between them.
//!
//! - Triangles are tested with the watertight intersection of Woop et al. 2013
//!   ([`ShearedRay`]) instead of obvhs's Möller–Trumbore test.
//! - Triangles and rays are scaled by a power of two that brings the scene's extent to
//!   about 2¹⁰. obvhs's CWBVH node test skips every node closer to the ray origin than
//!   t = 10⁻⁴ (an absolute constant), which in a scene a few 10⁻⁴ across culled a third
//!   of all hits; after scaling that is 10⁻⁷ of the scene, whatever its size. Scaling by
//!   a power of two is exact, so hits are bit-for-bit those of the unscaled test.
//! - The hierarchy is built over triangle bounds inflated by 10⁻⁶ of the scene's size:
//!   obvhs's slab tests are not conservative (a ray leaving a flat node exactly at its
//!   edge can round to a miss, and direction components under f32::EPSILON are replaced
//!   by ±EPSILON in the reciprocal), and the margin absorbs both.
//!
//! ```
//! use glam::Vec3;
//! use guiding_core::{Intersector, Ray, Triangle};
//! use guiding_obvhs::{BvhKind, ObvhsIntersector};
//!
//! let floor = [Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0))];
//! let bvh = ObvhsIntersector::build(&floor, BvhKind::default());
//! let hit = bvh.intersect(&Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::NEG_Y)).expect("straight down");
//! assert_eq!(hit.primitive, 0);
//! assert!((hit.t - 1.0).abs() < 1e-6);
//! assert!(bvh.occluded(&Ray::segment(Vec3::Y, Vec3::NEG_Y, 0.0, 2.0)));
//! ```

mod flat;
mod watertight;

use glam::{Vec2, Vec3, Vec3A};
use guiding_core::{Hit, Intersector, Ray, Triangle};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::{Boundable, BvhBuildParams};

pub use flat::{flat_bvh2, FlatBvh, FlatBvhNode};
pub use watertight::{PackedTriangle, ShearedRay, TriangleHit};

/// Which obvhs hierarchy to traverse.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BvhKind {
    /// Binary BVH (PLOC build with reinsertion).
    Bvh2,
    /// Compressed 8-wide BVH (Ylitie et al. 2017), 80-byte nodes, SIMD node tests.
    #[default]
    Cwbvh,
}

/// A triangle's bounds grown by a margin, which is all the builder sees of it.
struct InflatedBounds {
    min: Vec3A,
    max: Vec3A,
}

impl Boundable for InflatedBounds {
    fn aabb(&self) -> Aabb {
        Aabb::new(self.min, self.max)
    }
}

/// Relative margin of every triangle's bounds: covers slab-test rounding (a few ulps of
/// t and of coordinates) and the ±EPSILON reciprocal of nearly axis-parallel rays over
/// distances up to a few scene diameters.
const BOUNDS_MARGIN: f32 = 1e-6;

enum Hierarchy {
    Empty,
    Bvh2(Bvh2),
    Cwbvh(CwBvh),
}

/// log₂ of the size the local frame scales a scene to.
const LOCAL_SIZE_LOG2: i32 = 10;

/// Closest-hit and occlusion queries over a triangle list, through an obvhs BVH.
pub struct ObvhsIntersector {
    hierarchy: Hierarchy,
    /// `local = world · scale`, a power of two.
    scale: f32,
    /// `1 / scale`, exact: dividing by `scale` is multiplying by it.
    inverse_scale: f32,
    /// Triangles in BVH order (the order `primitive_indices` gives), for locality.
    triangles: Vec<PackedTriangle>,
    /// Index in the caller's slice of each triangle in BVH order.
    original_index: Vec<u32>,
}

impl ObvhsIntersector {
    /// Builds a BVH over `triangles` (in parallel with the `parallel` feature). Triangles
    /// with a non-finite coordinate are left out and never hit; hits report indices
    /// into `triangles`.
    pub fn build(triangles: &[Triangle], kind: BvhKind) -> Self {
        let kept: Vec<u32> = (0..triangles.len() as u32).filter(|&i| triangles[i as usize].is_finite()).collect();
        if kept.is_empty() {
            return Self {
                hierarchy: Hierarchy::Empty,
                scale: 1.0,
                inverse_scale: 1.0,
                triangles: Vec::new(),
                original_index: Vec::new(),
            };
        }
        let (low, high) = kept
            .iter()
            .flat_map(|&i| triangles[i as usize].vertices)
            .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(low, high), v| {
                (low.min(v), high.max(v))
            });
        let extent = (high - low).max_element();
        let magnitude = low.abs().max(high.abs()).max_element();
        let exponent = if extent > 0.0 && extent.is_finite() { ceil_log2(extent) } else { 0 };
        // Never so large that coordinates could overflow (|local| ≤ 2¹⁰⁰).
        let scale = power_of_two((LOCAL_SIZE_LOG2 - exponent).min(100 - ceil_log2(magnitude.max(1e-30))));
        let local: Vec<[Vec3; 3]> = kept.iter().map(|&i| triangles[i as usize].vertices.map(|v| v * scale)).collect();
        let (local_low, local_high) = (low * scale, high * scale);
        let size = (local_high - local_low).length() + local_low.abs().max(local_high.abs()).max_element();
        let margin = Vec3A::splat(BOUNDS_MARGIN * size);
        let bounds: Vec<InflatedBounds> = local
            .iter()
            .map(|vertices| {
                let [v0, v1, v2] = vertices.map(Vec3A::from);
                InflatedBounds { min: v0.min(v1).min(v2) - margin, max: v0.max(v1).max(v2) + margin }
            })
            .collect();
        let params = BvhBuildParams::medium_build();
        let mut build_time = std::time::Duration::default();
        let (hierarchy, primitive_indices) = match kind {
            BvhKind::Bvh2 => {
                let bvh = obvhs::bvh2::builder::build_bvh2(&bounds, params, &mut build_time);
                let indices = bvh.primitive_indices.clone();
                (Hierarchy::Bvh2(bvh), indices)
            }
            BvhKind::Cwbvh => {
                let bvh = obvhs::cwbvh::builder::build_cwbvh(&bounds, params, &mut build_time);
                let indices = bvh.primitive_indices.clone();
                (Hierarchy::Cwbvh(bvh), indices)
            }
        };
        let original_index: Vec<u32> = primitive_indices.iter().map(|&p| kept[p as usize]).collect();
        let triangles = primitive_indices.iter().map(|&p| PackedTriangle::new(local[p as usize])).collect();
        Self { hierarchy, scale, inverse_scale: 1.0 / scale, triangles, original_index }
    }

    /// Number of triangles in the hierarchy.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The ray in the local frame: same direction, t scaled by the (exact) power of two.
    #[inline]
    fn to_local(&self, ray: &Ray) -> LocalRay {
        LocalRay {
            origin: Vec3A::from(ray.origin) * self.scale,
            direction: ray.direction.into(),
            t_min: ray.t_min * self.scale,
            t_max: ray.t_max * self.scale,
        }
    }
}

/// A ray in the intersector's local frame, held in SIMD registers: a [`Ray`] written
/// field by field and read back as vectors stalls store-to-load forwarding on every query
/// (measured: about 6 % of an occlusion query).
#[derive(Clone, Copy)]
struct LocalRay {
    origin: Vec3A,
    direction: Vec3A,
    t_min: f32,
    t_max: f32,
}

impl LocalRay {
    /// The obvhs ray. Its reciprocal direction stays moderate (CWBVH's quantised node
    /// test loses all precision with huge reciprocals); the bounds margin covers the error.
    /// Negative zeros become positive: CWBVH orders children by the sign bit of the
    /// direction but obvhs takes the reciprocal of -0 as negative, and a ray along an axis
    /// written as (-1, -0, -0) then misses every node.
    #[inline]
    fn bvh_ray(&self) -> obvhs::ray::Ray {
        obvhs::ray::Ray::new(self.origin, self.direction + Vec3A::ZERO, self.t_min, self.t_max)
    }
}

/// The largest float below a finite `t` (∞ stays ∞, NaN stays NaN).
fn float_below(t: f32) -> f32 {
    if !t.is_finite() {
        t
    } else if t > 0.0 {
        f32::from_bits(t.to_bits() - 1)
    } else if t == 0.0 {
        -f32::from_bits(1)
    } else {
        f32::from_bits(t.to_bits() + 1)
    }
}

/// ⌈log₂ x⌉ for finite x > 0, from the f32 bits (this crate has no libm dependency).
fn ceil_log2(x: f32) -> i32 {
    let bits = x.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32 - 127;
    let mantissa = bits & 0x7f_ffff;
    if exponent == -127 {
        // Subnormal: treat as the smallest normal's exponent; the frame scale stays finite.
        -126
    } else if mantissa == 0 {
        exponent
    } else {
        exponent + 1
    }
}

/// 2^k as f32, with k clamped to the normal range.
fn power_of_two(k: i32) -> f32 {
    f32::from_bits(((k.clamp(-126, 127) + 127) as u32) << 23)
}

impl Intersector for ObvhsIntersector {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_traceable() {
            return None;
        }
        // The trait's segment is open at t_max; the watertight test's is closed (so that
        // the traversal's shrinking t_max still admits ties), so end one float earlier.
        let local = self.to_local(ray);
        let ray = LocalRay { t_max: float_below(local.t_max), ..local };
        let sheared = ShearedRay::new(ray.origin, ray.direction);
        // The traversal keeps the closest t as its t_max; ties (a ray through a shared
        // edge) go to the lower original index, so the answer does not depend on
        // traversal order.
        let mut best_slot = usize::MAX;
        let (mut best_t, mut best_barycentrics) = (f32::INFINITY, Vec2::ZERO);
        let test = |bvh_ray: &obvhs::ray::Ray, slot: usize| -> f32 {
            let Some(hit) = sheared.intersect_packed(&self.triangles[slot], ray.t_min, bvh_ray.tmax) else {
                return f32::INFINITY;
            };
            if hit.t < bvh_ray.tmax
                || best_slot == usize::MAX
                || self.original_index[slot] < self.original_index[best_slot]
            {
                (best_slot, best_t, best_barycentrics) = (slot, hit.t, hit.barycentrics);
            }
            hit.t
        };
        let mut record = RayHit::none();
        match &self.hierarchy {
            Hierarchy::Empty => {}
            Hierarchy::Bvh2(bvh) => {
                bvh.ray_traverse(ray.bvh_ray(), &mut record, test);
            }
            Hierarchy::Cwbvh(bvh) => {
                bvh.ray_traverse(ray.bvh_ray(), &mut record, test);
            }
        }
        let triangle = self.triangles.get(best_slot)?;
        let t =
            triangle.plane_t(ray.origin, ray.direction).filter(|&t| t > ray.t_min && t <= ray.t_max).unwrap_or(best_t);
        Some(Hit {
            t: t * self.inverse_scale,
            primitive: self.original_index[best_slot],
            barycentrics: best_barycentrics,
        })
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        if !ray.is_traceable() {
            return false;
        }
        let ray = self.to_local(ray);
        let sheared = ShearedRay::new(ray.origin, ray.direction);
        let test = |_: &obvhs::ray::Ray, slot: usize| -> f32 {
            // Strictly inside the segment: a shadow ray ending on the light is not blocked
            // by it. Any t below the traversal's t_max ends the traversal.
            if sheared.occludes_packed(&self.triangles[slot], ray.t_min, ray.t_max) {
                ray.t_min
            } else {
                f32::INFINITY
            }
        };
        match &self.hierarchy {
            Hierarchy::Empty => false,
            Hierarchy::Bvh2(bvh) => !bvh.ray_traverse_miss(ray.bvh_ray(), test),
            Hierarchy::Cwbvh(bvh) => !bvh.ray_traverse_miss(ray.bvh_ray(), test),
        }
    }
}
