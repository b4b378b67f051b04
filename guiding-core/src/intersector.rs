//! The [`Intersector`] trait: what a guide-driven integrator needs from a ray tracer.

use crate::geometry::{Hit, Ray};

/// Closest-hit and occlusion queries against a fixed set of triangles.
///
/// Adapters implement it over obvhs, Embree or a renderer's own BVH. Implementations
/// must be watertight (a ray through a shared edge hits one of the two triangles) and
/// safe to call from many threads at once.
pub trait Intersector: Sync {
    /// The closest hit with `ray.t_min < t < ray.t_max`, if any.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// Whether anything lies on the ray with `ray.t_min < t < ray.t_max` (any hit, not the closest).
    fn occluded(&self, ray: &Ray) -> bool;
}
