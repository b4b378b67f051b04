//! Rays, hits and triangles: the geometric vocabulary shared by intersectors and guides.

use glam::{Vec2, Vec3, Vec3A};

/// A ray `origin + t·direction` restricted to `t_min < t < t_max`.
///
/// Positions are in scene units; `direction` should be unit length so that `t` is a
/// distance in scene units (intersectors do not normalise it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point, scene units.
    pub origin: Vec3,
    /// Direction of travel, unit length.
    pub direction: Vec3,
    /// Hits at `t <= t_min` are ignored (self-intersection epsilon).
    pub t_min: f32,
    /// Hits at `t >= t_max` are ignored; `f32::INFINITY` for an unbounded ray.
    pub t_max: f32,
}

impl Ray {
    /// An unbounded ray starting at `origin` (`t_min = 0`, `t_max = ∞`).
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Self { origin, direction, t_min: 0.0, t_max: f32::INFINITY }
    }

    /// A ray limited to `t_min < t < t_max`, e.g. a shadow ray towards a light at distance `t_max`.
    pub fn segment(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Self {
        Self { origin, direction, t_min, t_max }
    }

    /// Whether the ray can be traced: finite origin and direction, a non-zero direction
    /// and a non-empty segment (`t_min < t_max`, neither NaN). Intersectors answer "no
    /// hit" for any other ray.
    ///
    /// ```
    /// use glam::Vec3;
    /// use guiding_core::Ray;
    /// assert!(Ray::new(Vec3::ZERO, Vec3::Z).is_traceable());
    /// assert!(!Ray::new(Vec3::NAN, Vec3::Z).is_traceable());
    /// assert!(!Ray::new(Vec3::ZERO, Vec3::ZERO).is_traceable());
    /// assert!(!Ray::segment(Vec3::ZERO, Vec3::Z, 1.0, 1.0).is_traceable());
    /// ```
    #[inline]
    pub fn is_traceable(&self) -> bool {
        // x·0 is ±0 for finite x and NaN otherwise: one SIMD test for all six coordinates
        // (this runs once per ray in every intersector).
        let (origin, direction) = (Vec3A::from(self.origin), Vec3A::from(self.direction));
        let finite = (origin * 0.0 + direction * 0.0).cmpeq(Vec3A::ZERO).all();
        finite && direction.cmpne(Vec3A::ZERO).any() && self.t_min < self.t_max
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// The closest intersection of a ray with the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit (distance when the direction is unit length).
    pub t: f32,
    /// Index of the triangle that was hit, in the order the intersector was built from.
    pub primitive: u32,
    /// Barycentric coordinates (b1, b2) of the hit: `p = (1-b1-b2)·v0 + b1·v1 + b2·v2`.
    pub barycentrics: Vec2,
}

/// A triangle given by its three vertices (scene units), counter-clockwise seen from the front.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// The vertices v0, v1, v2.
    pub vertices: [Vec3; 3],
}

impl Triangle {
    /// A triangle from its three vertices.
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        Self { vertices: [v0, v1, v2] }
    }

    /// `(v1 - v0) × (v2 - v0)`: twice the area times the front-facing unit normal.
    pub fn scaled_normal(&self) -> Vec3 {
        let [v0, v1, v2] = self.vertices;
        (v1 - v0).cross(v2 - v0)
    }

    /// Area in scene units squared (0 for a degenerate triangle).
    pub fn area(&self) -> f32 {
        0.5 * self.scaled_normal().length()
    }

    /// The geometric front normal `normalize((v1 - v0) × (v2 - v0))`, or `None` when the
    /// triangle is degenerate or not finite.
    pub fn normal(&self) -> Option<Vec3> {
        let n = self.scaled_normal().try_normalize()?;
        n.is_finite().then_some(n)
    }

    /// The point with barycentric coordinates (b1, b2).
    pub fn point(&self, barycentrics: Vec2) -> Vec3 {
        let [v0, v1, v2] = self.vertices;
        v0 * (1.0 - barycentrics.x - barycentrics.y) + v1 * barycentrics.x + v2 * barycentrics.y
    }

    /// Whether every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.vertices.iter().all(|v| v.is_finite())
    }
}

/// Maps a point of the unit square to barycentric coordinates uniformly distributed
/// over a triangle (the area-preserving square-root warp).
pub fn square_to_triangle_barycentrics(u: Vec2) -> Vec2 {
    let su = libm::sqrtf(u.x);
    Vec2::new(su * (1.0 - u.y), su * u.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_and_normal_of_a_right_triangle() {
        let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!(t.area(), 0.5);
        assert_eq!(t.normal(), Some(Vec3::Z));
    }

    #[test]
    fn degenerate_triangle_has_no_normal() {
        let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0);
        assert_eq!(t.area(), 0.0);
        assert_eq!(t.normal(), None);
        let nan = Triangle::new(Vec3::NAN, Vec3::X, Vec3::Y);
        assert_eq!(nan.normal(), None);
        assert!(!nan.is_finite());
    }

    #[test]
    fn warped_points_stay_inside_the_triangle() {
        for i in 0..32 {
            for j in 0..32 {
                let b = square_to_triangle_barycentrics(Vec2::new(i as f32 / 31.0, j as f32 / 31.0));
                assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6, "{b:?}");
            }
        }
    }
}
