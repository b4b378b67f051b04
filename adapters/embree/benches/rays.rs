//! Rays per second, closest hit and occlusion, for the Embree and obvhs adapters and for
//! the raw libraries beneath them (Embree's `rtcIntersect1`/`rtcOccluded1` on the same
//! scene; obvhs's CWBVH with its own Möller–Trumbore test), on one scene and one set of
//! rays: a 100k-triangle sphere in a box, 10⁵ incoherent rays from inside. One thread.
//!
//! `cargo bench -p guiding-embree --bench rays`

use std::f32::consts::PI;
use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::{Vec3, Vec3A};
use guiding_core::{Intersector, Pcg32, Ray, Triangle};
use guiding_embree::{sys, EmbreeIntersector};
use guiding_obvhs::{BvhKind, ObvhsIntersector};

/// A UV sphere of `2·rings·segments` triangles inside a box of 12.
fn scene() -> Vec<Triangle> {
    let (rings, segments) = (200, 250);
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

fn rays(count: usize) -> Vec<Ray> {
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

fn embree_ray(ray: &Ray, t_max: f32) -> sys::RTCRay {
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

fn bench_rays(c: &mut Criterion) {
    let triangles = scene();
    let rays = rays(100_000);
    let shadow: Vec<Ray> = rays.iter().map(|r| Ray { t_max: 4.0, ..*r }).collect();
    let embree = EmbreeIntersector::build(&triangles).expect("Embree builds");
    let obvhs = ObvhsIntersector::build(&triangles, BvhKind::Cwbvh);
    let raw_triangles: Vec<obvhs::triangle::Triangle> = triangles
        .iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: Vec3A::from(t.vertices[0]),
            v1: Vec3A::from(t.vertices[1]),
            v2: Vec3A::from(t.vertices[2]),
        })
        .collect();
    let raw_obvhs = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &raw_triangles,
        obvhs::BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let raw_ray = |r: &Ray| obvhs::ray::Ray::new(r.origin.into(), r.direction.into(), 0.0, r.t_max);

    let mut group = c.benchmark_group("rays");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group.sample_size(10);
    group.bench_function("closest/embree-adapter", |b| {
        b.iter(|| rays.iter().filter(|r| embree.intersect(r).is_some()).count())
    });
    group.bench_function("closest/embree-raw", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| {
                    let mut hit = sys::RTCRayHit {
                        ray: embree_ray(r, f32::INFINITY),
                        hit: sys::RTCHit { geomID: sys::RTC_INVALID_GEOMETRY_ID, ..Default::default() },
                    };
                    // SAFETY: the adapter's committed scene, an aligned RTCRayHit.
                    unsafe { sys::rtcIntersect1(embree.scene(), &mut hit, std::ptr::null_mut()) };
                    hit.hit.geomID != sys::RTC_INVALID_GEOMETRY_ID
                })
                .count()
        })
    });
    group.bench_function("closest/obvhs-adapter", |b| {
        b.iter(|| rays.iter().filter(|r| obvhs.intersect(r).is_some()).count())
    });
    group.bench_function("closest/obvhs-raw", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| {
                    let mut hit = obvhs::ray::RayHit::none();
                    raw_obvhs.ray_traverse(raw_ray(r), &mut hit, |ray, id| {
                        raw_triangles[raw_obvhs.primitive_indices[id] as usize].intersect(ray)
                    })
                })
                .count()
        })
    });
    group
        .bench_function("occluded/embree-adapter", |b| b.iter(|| shadow.iter().filter(|r| embree.occluded(r)).count()));
    group.bench_function("occluded/embree-raw", |b| {
        b.iter(|| {
            shadow
                .iter()
                .filter(|r| {
                    let mut ray = embree_ray(r, r.t_max);
                    // SAFETY: the adapter's committed scene, an aligned RTCRay.
                    unsafe { sys::rtcOccluded1(embree.scene(), &mut ray, std::ptr::null_mut()) };
                    ray.tfar == f32::NEG_INFINITY
                })
                .count()
        })
    });
    group.bench_function("occluded/obvhs-adapter", |b| b.iter(|| shadow.iter().filter(|r| obvhs.occluded(r)).count()));
    group.bench_function("occluded/obvhs-raw", |b| {
        b.iter(|| {
            shadow
                .iter()
                .filter(|r| {
                    !raw_obvhs.ray_traverse_miss(raw_ray(r), |ray, id| {
                        raw_triangles[raw_obvhs.primitive_indices[id] as usize].intersect(ray)
                    })
                })
                .count()
        })
    });
    group.finish();
    black_box(&rays);
}

criterion_group!(benches, bench_rays);
criterion_main!(benches);
