//! Adapter throughput ÷ raw library throughput, closest hit and occlusion, for Embree
//! and obvhs, with the two timed alternately on the same batch of rays round after round
//! (the order flipping each round), so drifting load on a shared machine hits both
//! alike. Prints the median ratio and its interquartile range over the rounds, and the
//! ratio of each side's fastest round with the throughputs (rays/s) it gives.
//!
//! `cargo bench -p guiding-embree --bench ray_ratios [-- ROUNDS]`

mod common;

use std::hint::black_box;
use std::time::Instant;

use common::{embree_raw_closest, embree_raw_occluded, rays, scene, RawObvhs};
use guiding_core::{Intersector, Ray};
use guiding_embree::EmbreeIntersector;
use guiding_obvhs::{BvhKind, ObvhsIntersector};

/// Seconds to run `query` over every ray, after one untimed pass: the raw obvhs side
/// has its own hierarchy and triangles, so each side would otherwise start every round
/// with the caches holding the other side's data (as a renderer, with one hierarchy,
/// never does).
fn seconds(rays: &[Ray], query: &dyn Fn(&Ray) -> bool) -> f64 {
    black_box(rays.iter().filter(|r| query(r)).count());
    let start = Instant::now();
    black_box(rays.iter().filter(|r| query(r)).count());
    start.elapsed().as_secs_f64()
}

fn main() {
    // `cargo bench` passes `--bench`; a bare number is the round count.
    let rounds = std::env::args().skip(1).find_map(|a| a.parse::<usize>().ok()).unwrap_or(41);
    let triangles = scene();
    let rays = rays(20_000);
    let shadow: Vec<Ray> = rays.iter().map(|r| Ray { t_max: 4.0, ..*r }).collect();
    let embree = EmbreeIntersector::build(&triangles).expect("Embree builds");
    let obvhs = ObvhsIntersector::build(&triangles, BvhKind::Cwbvh);
    let raw_obvhs = RawObvhs::build(&triangles);
    type Query<'a> = Box<dyn Fn(&Ray) -> bool + 'a>;
    let pairs: Vec<(&str, &[Ray], Query, Query)> = vec![
        (
            "closest/embree",
            &rays,
            Box::new(|r| embree.intersect(r).is_some()),
            Box::new(|r| embree_raw_closest(&embree, r)),
        ),
        ("closest/obvhs", &rays, Box::new(|r| obvhs.intersect(r).is_some()), Box::new(|r| raw_obvhs.closest(r))),
        ("occluded/embree", &shadow, Box::new(|r| embree.occluded(r)), Box::new(|r| embree_raw_occluded(&embree, r))),
        ("occluded/obvhs", &shadow, Box::new(|r| obvhs.occluded(r)), Box::new(|r| raw_obvhs.occluded(r))),
    ];
    println!("adapter ÷ raw throughput, {} rays per batch, {rounds} rounds", rays.len());
    for (name, batch, adapter, raw) in &pairs {
        let times: Vec<(f64, f64)> = (0..rounds)
            .map(|round| {
                if round % 2 == 0 {
                    let a = seconds(batch, adapter.as_ref());
                    (a, seconds(batch, raw.as_ref()))
                } else {
                    let r = seconds(batch, raw.as_ref());
                    (seconds(batch, adapter.as_ref()), r)
                }
            })
            .collect();
        let mut ratios: Vec<f64> = times.iter().map(|(a, r)| r / a).collect();
        ratios.sort_by(f64::total_cmp);
        let at = |q: f64| ratios[((ratios.len() - 1) as f64 * q).round() as usize];
        // Interruptions only ever add time, so each side's fastest round is its least
        // disturbed one.
        let fastest = |pick: fn(&(f64, f64)) -> f64| times.iter().map(pick).fold(f64::INFINITY, f64::min);
        let (adapter_best, raw_best) = (fastest(|t| t.0), fastest(|t| t.1));
        println!(
            "{name:16} median {:.3}  (quartiles {:.3} … {:.3}), fastest rounds {:.3} ({:.2} vs {:.2} Mrays/s)",
            at(0.5),
            at(0.25),
            at(0.75),
            raw_best / adapter_best,
            batch.len() as f64 / adapter_best * 1e-6,
            batch.len() as f64 / raw_best * 1e-6,
        );
    }
}
