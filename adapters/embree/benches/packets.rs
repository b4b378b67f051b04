//! Embree's 16-ray packets against its single rays, on the same incoherent rays:
//! `rtcIntersect16` and `rtcOccluded16` (what a vectorised path loop would call) against
//! `rtcIntersect1` and `rtcOccluded1` (what the path loop calls today), on the shared
//! 100k-triangle scene and on a small one of the size of the project's test scenes (a few
//! hundred triangles). The two are timed alternately round after round (the order flipping
//! each round), so drifting load on a shared machine hits both alike; prints the median
//! ratio of packet to single-ray throughput, its quartiles, and each side's fastest round.
//!
//! `cargo bench -p guiding-embree --bench packets [-- ROUNDS]`

// The shared module's raw single-ray calls and obvhs are the other benchmarks'.
#[allow(dead_code)]
mod common;

use std::hint::black_box;
use std::time::Instant;

use common::{embree_ray, rays, scene, small_scene};
use guiding_core::{Ray, Triangle};
use guiding_embree::{sys, EmbreeIntersector};

/// Lane masks of a full packet.
#[repr(C, align(64))]
struct Valid([i32; sys::PACKET_LANES]);

const ALL: Valid = Valid([-1; sys::PACKET_LANES]);

/// Rays hit, traced one at a time.
fn singles(scene: sys::RTCScene, rays: &[Ray], occlusion: bool) -> usize {
    let mut count = 0;
    for r in rays {
        let mut ray = embree_ray(r, r.t_max);
        if occlusion {
            // SAFETY: a committed scene, an aligned RTCRay.
            unsafe { sys::rtcOccluded1(scene, &mut ray, std::ptr::null_mut()) };
            count += (ray.tfar == f32::NEG_INFINITY) as usize;
        } else {
            let mut hit =
                sys::RTCRayHit { ray, hit: sys::RTCHit { geomID: sys::RTC_INVALID_GEOMETRY_ID, ..Default::default() } };
            // SAFETY: a committed scene, an aligned RTCRayHit.
            unsafe { sys::rtcIntersect1(scene, &mut hit, std::ptr::null_mut()) };
            count += (hit.hit.geomID != sys::RTC_INVALID_GEOMETRY_ID) as usize;
        }
    }
    count
}

/// Rays hit, traced 16 at a time (the ray count is a multiple of 16).
fn packets(scene: sys::RTCScene, rays: &[Ray], occlusion: bool) -> usize {
    let mut count = 0;
    let mut packet = sys::RTCRayHit16::default();
    for chunk in rays.chunks_exact(sys::PACKET_LANES) {
        let ray = &mut packet.ray;
        for (lane, r) in chunk.iter().enumerate() {
            ray.org_x[lane] = r.origin.x;
            ray.org_y[lane] = r.origin.y;
            ray.org_z[lane] = r.origin.z;
            ray.tnear[lane] = 0.0;
            ray.dir_x[lane] = r.direction.x;
            ray.dir_y[lane] = r.direction.y;
            ray.dir_z[lane] = r.direction.z;
            ray.tfar[lane] = r.t_max;
            ray.mask[lane] = u32::MAX;
            packet.hit.geomID[lane] = sys::RTC_INVALID_GEOMETRY_ID;
        }
        if occlusion {
            // SAFETY: a committed scene, an aligned RTCRay16 and valid mask.
            unsafe { sys::rtcOccluded16(ALL.0.as_ptr(), scene, &mut packet.ray, std::ptr::null_mut()) };
            count += packet.ray.tfar.iter().filter(|&&t| t == f32::NEG_INFINITY).count();
        } else {
            // SAFETY: a committed scene, an aligned RTCRayHit16 and valid mask.
            unsafe { sys::rtcIntersect16(ALL.0.as_ptr(), scene, &mut packet, std::ptr::null_mut()) };
            count += packet.hit.geomID.iter().filter(|&&g| g != sys::RTC_INVALID_GEOMETRY_ID).count();
        }
    }
    count
}

/// Seconds for one run of `trace`, after an untimed one.
fn seconds(trace: &dyn Fn() -> usize) -> f64 {
    black_box(trace());
    let start = Instant::now();
    black_box(trace());
    start.elapsed().as_secs_f64()
}

fn compare(name: &str, triangles: &[Triangle], rays: &[Ray], rounds: usize) {
    let embree = EmbreeIntersector::build(triangles).expect("Embree builds");
    let scene = embree.scene();
    for (kind, occlusion) in [("closest", false), ("occluded", true)] {
        let rays: Vec<Ray> =
            if occlusion { rays.iter().map(|r| Ray { t_max: 4.0, ..*r }).collect() } else { rays.to_vec() };
        assert_eq!(
            singles(scene, &rays, occlusion),
            packets(scene, &rays, occlusion),
            "{name}: packets hit as singles do"
        );
        let times: Vec<(f64, f64)> = (0..rounds)
            .map(|round| {
                let single = || singles(scene, &rays, occlusion);
                let packet = || packets(scene, &rays, occlusion);
                if round % 2 == 0 {
                    let s = seconds(&single);
                    (s, seconds(&packet))
                } else {
                    let p = seconds(&packet);
                    (seconds(&single), p)
                }
            })
            .collect();
        let mut ratios: Vec<f64> = times.iter().map(|(s, p)| s / p).collect();
        ratios.sort_by(f64::total_cmp);
        let at = |q: f64| ratios[((ratios.len() - 1) as f64 * q).round() as usize];
        let fastest = |pick: fn(&(f64, f64)) -> f64| times.iter().map(pick).fold(f64::INFINITY, f64::min);
        let (single_best, packet_best) = (fastest(|t| t.0), fastest(|t| t.1));
        println!(
            "{name:6} {kind:9} {:6} triangles: packet ÷ single throughput median {:.3} (quartiles {:.3} … {:.3}); fastest rounds {:.2} vs {:.2} Mrays/s",
            triangles.len(),
            at(0.5),
            at(0.25),
            at(0.75),
            rays.len() as f64 / packet_best * 1e-6,
            rays.len() as f64 / single_best * 1e-6,
        );
    }
}

fn main() {
    let rounds = std::env::args().skip(1).find_map(|a| a.parse::<usize>().ok()).unwrap_or(41);
    let rays = rays(20_000 / sys::PACKET_LANES * sys::PACKET_LANES);
    compare("large", &scene(), &rays, rounds);
    compare("small", &small_scene(), &rays, rounds);
}
