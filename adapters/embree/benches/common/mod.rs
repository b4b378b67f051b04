//! The scene, rays and raw library calls shared by the ray benchmarks: a 100k-triangle
//! sphere in a box, incoherent rays from inside, and each library's own entry points
//! called directly (Embree's `rtcIntersect1`/`rtcOccluded1`, obvhs's CWBVH with its own
//! Möller–Trumbore test) beside the adapters.

use std::f32::consts::PI;
use std::time::Duration;

use glam::{Vec3, Vec3A};
use guiding_core::{Pcg32, Ray, Triangle};
use guiding_embree::{sys, EmbreeIntersector};

/// A UV sphere of 100,000 triangles inside a box of 12.
pub fn scene() -> Vec<Triangle> {
    sphere_in_box(200, 250)
}

/// The same with a sphere of 240 triangles: the size of the project's test scenes.
#[allow(dead_code)] // Only the packet benchmark uses it.
pub fn small_scene() -> Vec<Triangle> {
    sphere_in_box(10, 12)
}

/// A UV sphere of `2·rings·segments` triangles inside a box of 12.
fn sphere_in_box(rings: u32, segments: u32) -> Vec<Triangle> {
    let point = |i: u32, j: u32| {
        let (theta, phi) = (PI * i as f32 / rings as f32, 2.0 * PI * j as f32 / segments as f32);
        Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * 2.0
    };
    let mut triangles = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            triangles.push(Triangle::new(a, b, c));
            triangles.push(Triangle::new(a, c, d));
        }
    }
    let s = 6.0;
    let corner = |x: f32, y: f32, z: f32| Vec3::new(x * s, y * s, z * s);
    for (a, b, c, d) in [
        (corner(-1., -1., -1.), corner(1., -1., -1.), corner(1., -1., 1.), corner(-1., -1., 1.)),
        (corner(-1., 1., -1.), corner(-1., 1., 1.), corner(1., 1., 1.), corner(1., 1., -1.)),
        (corner(-1., -1., -1.), corner(-1., -1., 1.), corner(-1., 1., 1.), corner(-1., 1., -1.)),
        (corner(1., -1., -1.), corner(1., 1., -1.), corner(1., 1., 1.), corner(1., -1., 1.)),
        (corner(-1., -1., -1.), corner(-1., 1., -1.), corner(1., 1., -1.), corner(1., -1., -1.)),
        (corner(-1., -1., 1.), corner(1., -1., 1.), corner(1., 1., 1.), corner(-1., 1., 1.)),
    ] {
        triangles.push(Triangle::new(a, b, c));
        triangles.push(Triangle::new(a, c, d));
    }
    triangles
}

pub fn rays(count: usize) -> Vec<Ray> {
    let mut rng = Pcg32::new(11, 3);
    (0..count)
        .map(|_| {
            let origin = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0) * 5.0;
            let direction = loop {
                let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                if let Some(unit) = v.try_normalize().filter(|_| v.length_squared() <= 1.0) {
                    break unit;
                }
            };
            Ray::new(origin, direction)
        })
        .collect()
}

pub fn embree_ray(ray: &Ray, t_max: f32) -> sys::RTCRay {
    sys::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        dir_x: ray.direction.x,
        dir_y: ray.direction.y,
        dir_z: ray.direction.z,
        tfar: t_max,
        mask: u32::MAX,
        ..Default::default()
    }
}

/// Closest hit through Embree's own call on the adapter's scene: whether it hit.
pub fn embree_raw_closest(embree: &EmbreeIntersector, r: &Ray) -> bool {
    let mut hit = sys::RTCRayHit {
        ray: embree_ray(r, f32::INFINITY),
        hit: sys::RTCHit { geomID: sys::RTC_INVALID_GEOMETRY_ID, ..Default::default() },
    };
    // SAFETY: the adapter's committed scene, an aligned RTCRayHit.
    unsafe { sys::rtcIntersect1(embree.scene(), &mut hit, std::ptr::null_mut()) };
    hit.hit.geomID != sys::RTC_INVALID_GEOMETRY_ID
}

/// Occlusion through Embree's own call on the adapter's scene: whether it is blocked.
pub fn embree_raw_occluded(embree: &EmbreeIntersector, r: &Ray) -> bool {
    let mut ray = embree_ray(r, r.t_max);
    // SAFETY: the adapter's committed scene, an aligned RTCRay.
    unsafe { sys::rtcOccluded1(embree.scene(), &mut ray, std::ptr::null_mut()) };
    ray.tfar == f32::NEG_INFINITY
}

/// obvhs used directly: its CWBVH over the scene's triangles and its own triangle test.
pub struct RawObvhs {
    triangles: Vec<obvhs::triangle::Triangle>,
    bvh: obvhs::cwbvh::CwBvh,
}

impl RawObvhs {
    /// Builds the CWBVH the way obvhs's own examples do.
    pub fn build(triangles: &[Triangle]) -> Self {
        let triangles: Vec<obvhs::triangle::Triangle> = triangles
            .iter()
            .map(|t| obvhs::triangle::Triangle {
                v0: Vec3A::from(t.vertices[0]),
                v1: Vec3A::from(t.vertices[1]),
                v2: Vec3A::from(t.vertices[2]),
            })
            .collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &triangles,
            obvhs::BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        Self { triangles, bvh }
    }

    fn ray(r: &Ray) -> obvhs::ray::Ray {
        obvhs::ray::Ray::new(r.origin.into(), r.direction.into(), 0.0, r.t_max)
    }

    /// Whether the ray hits anything (closest-hit traversal).
    pub fn closest(&self, r: &Ray) -> bool {
        let mut hit = obvhs::ray::RayHit::none();
        self.bvh.ray_traverse(Self::ray(r), &mut hit, |ray, id| {
            self.triangles[self.bvh.primitive_indices[id] as usize].intersect(ray)
        })
    }

    /// Whether the segment is blocked (any-hit traversal).
    pub fn occluded(&self, r: &Ray) -> bool {
        !self.bvh.ray_traverse_miss(Self::ray(r), |ray, id| {
            self.triangles[self.bvh.primitive_indices[id] as usize].intersect(ray)
        })
    }
}
