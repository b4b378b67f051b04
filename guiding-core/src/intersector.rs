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

    /// The closest hits of a batch of rays: `hits[i]` is [`intersect`](Self::intersect)'s
    /// answer for `rays[i]` (the pairs beyond the shorter slice are left alone). The
    /// default traces them one at a time; an adapter with packet traversal (Embree's
    /// 16-ray packets) traces them together, with the answers a single ray gets.
    ///
    /// ```
    /// use glam::Vec3;
    /// use guiding_core::{Hit, Intersector, Ray};
    ///
    /// /// The plane z = 1, seen from below.
    /// struct Ceiling;
    /// impl Intersector for Ceiling {
    ///     fn intersect(&self, ray: &Ray) -> Option<Hit> {
    ///         let t = (1.0 - ray.origin.z) / ray.direction.z;
    ///         (t > ray.t_min && t < ray.t_max).then(|| Hit { t, primitive: 0, barycentrics: glam::Vec2::ZERO })
    ///     }
    ///     fn occluded(&self, ray: &Ray) -> bool {
    ///         self.intersect(ray).is_some()
    ///     }
    /// }
    ///
    /// let rays = [Ray::new(Vec3::ZERO, Vec3::Z), Ray::new(Vec3::ZERO, -Vec3::Z)];
    /// let mut hits = [None; 2];
    /// Ceiling.intersect_many(&rays, &mut hits);
    /// assert_eq!(hits[0].map(|h| h.t), Some(1.0));
    /// assert!(hits[1].is_none());
    /// ```
    fn intersect_many(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.intersect(ray);
        }
    }

    /// Occlusion of a batch of rays: `occluded[i]` is [`occluded`](Self::occluded)'s
    /// answer for `rays[i]`, traced one at a time by default, as packets where the
    /// adapter has them.
    fn occluded_many(&self, rays: &[Ray], occluded: &mut [bool]) {
        for (ray, blocked) in rays.iter().zip(occluded) {
            *blocked = self.occluded(ray);
        }
    }
}
