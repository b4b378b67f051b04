//! Nanoseconds per guide operation on a 1,000-probe hemisphere grid over a closed box
//! (the Cornell box's walls): locate, sample, pdf, update, estimate, rebuild; and on a
//! learned spatial × directional tree over the same box: a render-time vertex (locate,
//! distribution, sample, pdf; and each part apart, also on an untaught tree), a record
//! learned in place, and one pushed to a thread's
//! records and splatted between passes (each timed apart); and on a focal guide taught
//! an opening in the box: its pdf of a direction (half of them drawn towards its boxes)
//! and a sample.
//!
//! `cargo bench --bench guide_operations`

#[path = "../guiding-core/tests/support/mod.rs"]
mod support;

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use glam::{Vec2, Vec3};
use guiding_core::focal::{FocalGuide, FocalGuideSettings, FocalRecord};
use guiding_core::{
    DirectionalDistribution, Guide, HemisphereGrid, HemisphereGridSettings, Lambertian, Pcg32, ProbeSet,
    SpatialDirectionalTree, SpatialDirectionalTreeSettings, TreeRecords,
};

fn bench(c: &mut Criterion) {
    let walls = support::box_walls();
    // 1,000 probes of 8×16 patches with their candidate table pass the default 2 MiB.
    let settings = HemisphereGridSettings { probe_count: Some(1000), budget_bytes: 4 << 20, ..Default::default() };
    let mut grid = HemisphereGrid::build(&walls, settings).expect("grid");
    // Query points: another low-discrepancy set on the same walls, offset so they are
    // not the probes themselves.
    let queries = ProbeSet::place_on_triangles(&walls, 4093, false).expect("queries");
    let regions: Vec<_> = queries
        .positions
        .iter()
        .zip(&queries.normals)
        .map(|(&p, &n)| grid.locate(p, n).expect("every wall point has a probe"))
        .collect();
    let mut rng = Pcg32::new(1, 2);
    // Teach every probe something so the CDFs are not flat.
    for (i, &region) in regions.iter().enumerate() {
        for _ in 0..64 {
            let s = grid.sample(region, rng.next_vec2());
            grid.update(region, s.direction, (i % 7) as f32 * s.direction.length());
        }
    }
    grid.rebuild_sampling();
    let uniforms: Vec<Vec2> = (0..4096).map(|_| rng.next_vec2()).collect();
    let directions: Vec<Vec3> = regions.iter().zip(&uniforms).map(|(&r, &u)| grid.sample(r, u).direction).collect();

    let mut i = 0usize;
    let mut next = || {
        i = (i + 1) % regions.len();
        i
    };
    c.bench_function("locate", |b| {
        b.iter(|| {
            let k = next();
            black_box(grid.locate(black_box(queries.positions[k]), black_box(queries.normals[k])))
        })
    });
    c.bench_function("sample", |b| {
        b.iter(|| {
            let k = next();
            black_box(grid.sample(black_box(regions[k]), black_box(uniforms[k])))
        })
    });
    c.bench_function("pdf", |b| {
        b.iter(|| {
            let k = next();
            black_box(grid.pdf(black_box(regions[k]), black_box(directions[k])))
        })
    });
    c.bench_function("update", |b| {
        b.iter(|| {
            let k = next();
            black_box(grid.update(black_box(regions[k]), black_box(directions[k]), black_box(0.5)))
        })
    });
    c.bench_function("estimate_integral_lambertian", |b| {
        b.iter(|| {
            let k = next();
            let bsdf = Lambertian { normal: queries.normals[k], albedo: 0.7 };
            black_box(grid.estimate_integral(black_box(regions[k]), queries.normals[k], &bsdf, uniforms[k]))
        })
    });
    // A rebuild only touches probes updated since the last one: touch them all first
    // (untimed), so this is the cost of a full rebuild after a pass.
    c.bench_function("rebuild_sampling_all_1000_probes", |b| {
        b.iter_custom(|iterations| {
            let mut total = std::time::Duration::ZERO;
            for _ in 0..iterations {
                for (&region, &direction) in regions.iter().zip(&directions) {
                    grid.update(region, direction, 0.5);
                }
                let start = std::time::Instant::now();
                grid.rebuild_sampling();
                total += start.elapsed();
            }
            total
        })
    });
    println!(
        "grid: {} probes x {} patches, {} bytes; default settings would hold {} probes in {} bytes",
        grid.probe_count(),
        grid.patch_count(),
        grid.memory_bytes(),
        HemisphereGridSettings::default().resolve_probe_count().unwrap(),
        HemisphereGrid::build(&walls, HemisphereGridSettings::default()).unwrap().memory_bytes(),
    );
}

/// A tree taught, epoch after epoch, a light in one corner of the box seen from every
/// wall point (radiance falling off sharply around its direction), then timed.
fn bench_tree(c: &mut Criterion) {
    let walls = support::box_walls();
    let queries = ProbeSet::place_on_triangles(&walls, 4093, false).expect("queries");
    let mut tree = SpatialDirectionalTree::new(Vec3::NEG_ONE, Vec3::ONE, SpatialDirectionalTreeSettings::default())
        .expect("tree over the box");
    let light = Vec3::new(0.8, 0.95, 0.8);
    let mut rng = Pcg32::new(3, 4);
    for _epoch in 0..8 {
        for _ in 0..100 {
            for (&p, &n) in queries.positions.iter().zip(&queries.normals) {
                let region = tree.locate(p, n).expect("a leaf");
                let s = tree.sample(region, rng.next_vec2());
                let to_light = (light - p).normalize_or_zero();
                let target = 0.1 + 100.0 * s.direction.dot(to_light).max(0.0).powi(200);
                tree.update_sampled(region, s.direction, target, s.pdf);
            }
        }
        tree.rebuild_sampling();
    }
    let uniforms: Vec<Vec2> = (0..queries.positions.len()).map(|_| rng.next_vec2()).collect();
    let mut i = 0usize;
    // TREE_QUERIES=N times the vertex over the first N queries alone: with 16 every node
    // it reads stays in L1, which tells the descents' latency from cache misses.
    let count = std::env::var("TREE_QUERIES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(usize::MAX)
        .clamp(1, queries.positions.len());
    c.bench_function("tree_vertex_locate_distribution_sample_pdf", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            let region = tree.locate(black_box(queries.positions[i]), black_box(queries.normals[i])).expect("a leaf");
            let distribution = tree.distribution(region);
            let s = distribution.sample(black_box(uniforms[i]));
            black_box(distribution.pdf(black_box(s.direction)))
        })
    });
    // The vertex's parts timed apart (the distribution's set-up in each of the last two),
    // and a tree that was never taught (its root alone) to tell the parts' fixed cost from
    // their descents': regions whose normal lies along the leaf's axis, as most do.
    let regions: Vec<_> = (0..count).map(|k| tree.locate(queries.positions[k], queries.normals[k]).unwrap()).collect();
    let directions: Vec<_> = (0..count).map(|k| tree.sample(regions[k], uniforms[k]).direction).collect();
    c.bench_function("tree_vertex_part_locate", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            black_box(tree.locate(black_box(queries.positions[i]), black_box(queries.normals[i])))
        })
    });
    c.bench_function("tree_vertex_part_distribution", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            black_box(tree.distribution(black_box(regions[i])));
        })
    });
    c.bench_function("tree_vertex_part_sample", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            black_box(tree.distribution(black_box(regions[i])).sample(black_box(uniforms[i])))
        })
    });
    c.bench_function("tree_vertex_part_pdf", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            black_box(tree.distribution(black_box(regions[i])).pdf(black_box(directions[i])))
        })
    });
    let untaught = SpatialDirectionalTree::new(Vec3::NEG_ONE, Vec3::ONE, SpatialDirectionalTreeSettings::default())
        .expect("tree over the box");
    // An untaught leaf's square is built around z: the floor's and ceiling's points.
    let along_z: Vec<_> = (0..queries.positions.len())
        .filter(|&k| queries.normals[k].z.abs() > 0.99)
        .map(|k| untaught.locate(queries.positions[k], queries.normals[k]).expect("a leaf"))
        .collect();
    let along_z_directions: Vec<_> =
        along_z.iter().zip(&uniforms).map(|(&r, &u)| untaught.sample(r, u).direction).collect();
    let mut j = 0usize;
    c.bench_function("tree_vertex_part_sample_untaught", |b| {
        b.iter(|| {
            j = (j + 1) % along_z.len();
            black_box(untaught.distribution(black_box(along_z[j])).sample(black_box(uniforms[j])))
        })
    });
    c.bench_function("tree_vertex_part_pdf_untaught", |b| {
        b.iter(|| {
            j = (j + 1) % along_z.len();
            black_box(untaught.distribution(black_box(along_z[j])).pdf(black_box(along_z_directions[j])))
        })
    });
    let records: Vec<_> = (0..count)
        .map(|k| {
            let region = tree.locate(queries.positions[k], queries.normals[k]).expect("a leaf");
            let s = tree.sample(region, uniforms[k]);
            (region, s)
        })
        .collect();
    c.bench_function("tree_record", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            let (region, s) = records[i];
            black_box(tree.update_sampled(black_box(region), black_box(s.direction), black_box(0.5), s.pdf))
        })
    });
    // Per-thread records: the push a vertex pays during the pass, the map its worker
    // does after the pass (`prepare_splat`) and the splat that learns it between passes,
    // timed apart (records made 4096 at a time, as a worker's share of a pass would be).
    let regions: Vec<_> = records.iter().map(|r| r.0).collect();
    let directions: Vec<_> = records.iter().map(|r| r.1.direction).collect();
    let pdfs: Vec<_> = records.iter().map(|r| r.1.pdf).collect();
    let mut buffer = TreeRecords::default();
    let mut time_records = |phase: usize, iters: u64| {
        let mut times = [Duration::ZERO; 3];
        let mut done = 0u64;
        while done < iters {
            let chunk = (iters - done).min(4096);
            let start = Instant::now();
            for _ in 0..chunk {
                i = (i + 1) % count;
                // Read from the arrays as a renderer reads its path's stored vertices
                // (no black_box on them: it stores the direction in two parts that the
                // push then loads across, a store-forwarding stall of a few ns).
                black_box(tree.record(&mut buffer, regions[i], directions[i], 0.5, pdfs[i]));
            }
            times[0] += start.elapsed();
            let start = Instant::now();
            tree.prepare_splat(black_box(&mut buffer));
            times[1] += start.elapsed();
            let start = Instant::now();
            black_box(tree.splat(&mut buffer));
            times[2] += start.elapsed();
            done += chunk;
        }
        times[phase]
    };
    c.bench_function("tree_record_push", |b| b.iter_custom(|iters| time_records(0, iters)));
    c.bench_function("tree_record_prepare", |b| b.iter_custom(|iters| time_records(1, iters)));
    c.bench_function("tree_record_splat", |b| b.iter_custom(|iters| time_records(2, iters)));
    let stats = tree.stats();
    println!(
        "tree: {} leaves, {} directional nodes (deepest {}), {} bytes",
        tree.leaf_count(),
        tree.directional_node_count(),
        (0..tree.leaf_count() as u32).map(|l| tree.directional_depth(l)).max().unwrap_or(0),
        stats.memory_bytes
    );
}

/// A focal guide taught, round after round, segments from every wall point through a
/// slit near the box's centre (a door left ajar), then timed at the same wall points.
fn bench_focal(c: &mut Criterion) {
    let walls = support::box_walls();
    let queries = ProbeSet::place_on_triangles(&walls, 4093, false).expect("queries");
    let mut guide =
        FocalGuide::new(Vec3::NEG_ONE, Vec3::ONE, FocalGuideSettings::default()).expect("focal guide over the box");
    let mut rng = Pcg32::new(5, 6);
    for _round in 0..6 {
        for _ in 0..20 {
            for &p in &queries.positions {
                let slit = Vec3::new(0.1 + 0.02 * rng.next_f32(), 0.8 * rng.next_f32() - 0.4, 0.02 * rng.next_f32());
                let direction = (slit - p).normalize_or(Vec3::X);
                let record = FocalRecord { origin: p, direction, length: f32::INFINITY, weight: 1.0 };
                guide.record(&record, rng.next_f32());
            }
        }
        guide.rebuild_sampling();
    }
    let count = queries.positions.len();
    let uniforms: Vec<(f32, Vec3)> =
        (0..count).map(|_| (rng.next_f32(), Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))).collect();
    // Half towards the boxes, half uniform over the sphere (most of which miss them).
    let directions: Vec<Vec3> = (0..count)
        .map(|k| {
            let (u_box, u) = uniforms[k];
            let towards = guide.sample(queries.positions[k], u_box, u).map(|s| s.direction);
            let z = 2.0 * u.x - 1.0;
            let phi = core::f32::consts::TAU * u.y;
            let r = (1.0 - z * z).max(0.0).sqrt();
            towards.filter(|_| k % 2 == 0).unwrap_or(Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect();
    let mut i = 0usize;
    c.bench_function("focal_pdf", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            black_box(guide.pdf(black_box(queries.positions[i]), black_box(directions[i])))
        })
    });
    c.bench_function("focal_sample", |b| {
        b.iter(|| {
            i = (i + 1) % count;
            let (u_box, u) = uniforms[i];
            black_box(guide.sample(black_box(queries.positions[i]), black_box(u_box), black_box(u)))
        })
    });
    println!("focal: {} boxes, {} octree nodes", guide.boxes().len(), guide.node_count());
}

criterion_group!(benches, bench, bench_tree, bench_focal);
criterion_main!(benches);
