//! Rays per second, closest hit and occlusion, for the Embree and obvhs adapters and for
//! the raw libraries beneath them (Embree's `rtcIntersect1`/`rtcOccluded1` on the same
//! scene; obvhs's CWBVH with its own Möller–Trumbore test), on one scene and one set of
//! rays: a 100k-triangle sphere in a box, 10⁵ incoherent rays from inside. One thread.
//! `ray_ratios` measures the adapter/raw ratios with the two interleaved.
//!
//! `cargo bench -p guiding-embree --bench rays`

mod common;

use std::hint::black_box;

use common::{embree_raw_closest, embree_raw_occluded, rays, scene, RawObvhs};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use guiding_core::{Intersector, Ray};
use guiding_embree::EmbreeIntersector;
use guiding_obvhs::{BvhKind, ObvhsIntersector};

fn bench_rays(c: &mut Criterion) {
    let triangles = scene();
    let rays = rays(100_000);
    let shadow: Vec<Ray> = rays.iter().map(|r| Ray { t_max: 4.0, ..*r }).collect();
    let embree = EmbreeIntersector::build(&triangles).expect("Embree builds");
    let obvhs = ObvhsIntersector::build(&triangles, BvhKind::Cwbvh);
    let raw_obvhs = RawObvhs::build(&triangles);

    let mut group = c.benchmark_group("rays");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group.sample_size(10);
    group.bench_function("closest/embree-adapter", |b| {
        b.iter(|| rays.iter().filter(|r| embree.intersect(r).is_some()).count())
    });
    group.bench_function("closest/embree-raw", |b| {
        b.iter(|| rays.iter().filter(|r| embree_raw_closest(&embree, r)).count())
    });
    group.bench_function("closest/obvhs-adapter", |b| {
        b.iter(|| rays.iter().filter(|r| obvhs.intersect(r).is_some()).count())
    });
    group.bench_function("closest/obvhs-raw", |b| b.iter(|| rays.iter().filter(|r| raw_obvhs.closest(r)).count()));
    group
        .bench_function("occluded/embree-adapter", |b| b.iter(|| shadow.iter().filter(|r| embree.occluded(r)).count()));
    group.bench_function("occluded/embree-raw", |b| {
        b.iter(|| shadow.iter().filter(|r| embree_raw_occluded(&embree, r)).count())
    });
    group.bench_function("occluded/obvhs-adapter", |b| b.iter(|| shadow.iter().filter(|r| obvhs.occluded(r)).count()));
    group.bench_function("occluded/obvhs-raw", |b| b.iter(|| shadow.iter().filter(|r| raw_obvhs.occluded(r)).count()));
    group.finish();
    black_box(&rays);
}

criterion_group!(benches, bench_rays);
criterion_main!(benches);
