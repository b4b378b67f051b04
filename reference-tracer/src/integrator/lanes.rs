//! `nee`'s camera paths traced in lanes: a thread keeps several paths in flight, traces
//! all their next rays as one batch ([`Intersector::intersect_many`]: Embree's 16-ray
//! packets), shades their vertices one lane after another, and traces their shadow rays
//! as another batch ([`Intersector::occluded_many`]); a lane whose path ends takes the
//! next pixel. Each path draws from its own pixel's generator in the order a path traced
//! alone does, and adds its light in the same order, so the image is the one-path-at-a-
//! time loop's ([`PathTracer::radiance`]) to the last bit wherever the batch answers as
//! single rays do (both adapters do) and no light or environment guide learns from the
//! light samples (their records then come in another order: the same image within noise).
//!
//! On door 160×120 and cornell 128² (Embree, 16 lanes, one thread) the loop traces
//! 1.11–1.14× the paths/s of one path at a time: the packets, and the lanes' independent
//! vertices overlapping in the core.

use glam::Vec3;
use guiding_core::{Guide, Hit, Intersector, Pcg32, Ray};

use super::counters::PathCounters;
use super::direct::PendingLightSample;
use super::method::Method;
use super::tracer::{nee_partner_pdf, GuideClock, NeeCells, NeeRecords, PathTracer, SurfaceInteraction};

/// A camera path in flight.
struct LanePath {
    /// Its pixel, as an index into the pixels being traced.
    pixel: usize,
    rng: Pcg32,
    /// The ray to trace next.
    ray: Ray,
    /// Scattering vertices so far.
    depth: u32,
    throughput: Vec3,
    radiance: Vec3,
    /// The previous vertex: its position, the pdf of the direction it scattered, whether
    /// that came from a delta lobe, and its light guide cell (what MIS weighs emission by).
    previous: Option<(Vec3, f32, bool, NeeCells)>,
    /// Whether the path has ended (its light sample, if any, still to be added).
    done: bool,
}

/// A lane's light sample waiting for its shadow ray, with what adding it needs.
struct LaneLightSample {
    lane: usize,
    pending: PendingLightSample,
    surface: SurfaceInteraction,
    cells: NeeCells,
    /// The path's throughput at the vertex.
    throughput: Vec3,
}

/// One thread's space for the lane loop, reused from row to row.
#[derive(Default)]
pub struct LaneScratch {
    paths: Vec<LanePath>,
    rays: Vec<Ray>,
    hits: Vec<Option<Hit>>,
    light_samples: Vec<LaneLightSample>,
    shadow_rays: Vec<Ray>,
    blocked: Vec<bool>,
}

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// Whether this pass's camera paths are traced in lanes: `nee` with more than one
    /// lane, and nothing at a vertex that the lanes leave out (directional and focal
    /// guides, the efficiency-aware roulette, the next-event gate, opacity masks).
    pub fn traces_in_lanes(&self) -> bool {
        self.settings.lanes > 1
            && self.settings.method == Method::Nee
            && self.guide.is_none()
            && self.focal.is_none()
            && self.roulette.is_none()
            && self.gate.is_none()
            && !self.masks
    }

    /// The radiance of one camera path per pixel of `out` (its pixel (x, y) given by
    /// `pixel_of`, its generator by `rng_of`), [`settings`](Self::settings)`.lanes` paths
    /// at a time; counters added to `counters`, the light and environment guides' records
    /// to `records`.
    pub fn radiance_in_lanes(
        &self,
        out: &mut [Vec3],
        pixel_of: impl Fn(usize) -> (u32, u32),
        rng_of: impl Fn(usize) -> Pcg32,
        scratch: &mut LaneScratch,
        records: &mut NeeRecords,
        counters: &mut PathCounters,
    ) {
        let lanes = self.settings.lanes.max(1) as usize;
        let mut next_pixel = 0;
        scratch.paths.clear();
        let mut clock = GuideClock::default();
        loop {
            while scratch.paths.len() < lanes && next_pixel < out.len() {
                let mut rng = rng_of(next_pixel);
                let (x, y) = pixel_of(next_pixel);
                let ray = self.camera_ray(x, y, &mut rng);
                counters.paths += 1;
                scratch.paths.push(LanePath {
                    pixel: next_pixel,
                    rng,
                    ray,
                    depth: 0,
                    throughput: Vec3::ONE,
                    radiance: Vec3::ZERO,
                    previous: None,
                    done: false,
                });
                next_pixel += 1;
            }
            if scratch.paths.is_empty() {
                return;
            }
            let LaneScratch { paths, rays, hits, light_samples, shadow_rays, blocked } = scratch;
            rays.clear();
            rays.extend(paths.iter().map(|p| p.ray));
            hits.clear();
            hits.resize(rays.len(), None);
            counters.rays += rays.len() as u64;
            self.intersector.intersect_many(rays, hits);
            light_samples.clear();
            for (lane, (path, hit)) in paths.iter_mut().zip(hits.iter()).enumerate() {
                self.lane_vertex(lane, path, *hit, light_samples, (&mut clock, records), counters);
            }
            shadow_rays.clear();
            shadow_rays.extend(light_samples.iter().map(|s| s.pending.ray));
            blocked.clear();
            blocked.resize(shadow_rays.len(), false);
            self.intersector.occluded_many(shadow_rays, blocked);
            for (sample, &blocked) in light_samples.iter().zip(blocked.iter()) {
                let transmittance = if blocked { 0.0 } else { 1.0 };
                let path = &mut paths[sample.lane];
                let direct = self.finish_light_sample(
                    &sample.pending,
                    transmittance,
                    &sample.surface,
                    sample.cells,
                    (None, 0.0, 0.0),
                    (&mut clock, records),
                    // The path's number only sets the gate's stride, and lanes run ungated.
                    counters.paths,
                );
                path.radiance += sample.throughput * direct.radiance;
            }
            // Ended paths give their lanes to the next pixels.
            let mut lane = 0;
            while lane < paths.len() {
                if paths[lane].done {
                    let path = paths.swap_remove(lane);
                    if path.radiance.max_element() > 0.0 {
                        counters.nonzero_paths += 1;
                    }
                    out[path.pixel] = path.radiance;
                } else {
                    lane += 1;
                }
            }
        }
    }

    /// One vertex of `path` (in lane `lane`) at `hit`, as [`radiance`](Self::radiance)
    /// takes it without guides: emission, the light sample (left in `light_samples` for
    /// its shadow ray), Russian roulette and the scattered direction, the next ray; or
    /// the path's end.
    fn lane_vertex(
        &self,
        lane: usize,
        path: &mut LanePath,
        hit: Option<Hit>,
        light_samples: &mut Vec<LaneLightSample>,
        (clock, records): (&mut GuideClock, &mut NeeRecords),
        counters: &mut PathCounters,
    ) {
        let settings = &self.settings;
        let ray = path.ray;
        let Some(hit) = hit else {
            if let Some(environment) = &self.scene.environment {
                let emitted = environment.radiance(ray.direction);
                let light_pdf = |from, _: NeeCells| {
                    self.environment_choice * self.environment_pdf(environment, from, ray.direction)
                };
                let (weight, _) = self.emission_weight(path.previous, light_pdf);
                path.radiance += path.throughput * (emitted * weight);
            }
            path.done = true;
            return;
        };
        let (material, _) = self.scene.material_at(hit.primitive, hit.barycentrics);
        counters.vertices += 1;
        let surface = self.interaction(&hit, material, ray.direction);
        let SurfaceInteraction { point, geometric_normal, wo, ref material, ref shading } = surface;
        if material.is_emissive() && geometric_normal.dot(wo) > 0.0 {
            let light_pdf = |from, cells: NeeCells| self.light_pdf(&hit, from, cells.light, point, geometric_normal);
            let (weight, _) = self.emission_weight(path.previous, light_pdf);
            path.radiance += path.throughput * (material.emission * weight);
        }
        let depth = path.depth;
        if depth + 1 >= settings.max_depth {
            path.done = true;
            return;
        }
        let delta = material.is_delta();
        let nee_cells = if delta { NeeCells::default() } else { self.nee_cells(point) };
        let rng = &mut path.rng;
        let pending =
            if delta { None } else { self.draw_light_sample(&surface, nee_cells, rng, (clock, records), counters) };
        let throughput = path.throughput;
        // Russian roulette before the direction is drawn, by the throughput.
        let mut survival = 1.0;
        let mut ends = false;
        if depth + 1 >= settings.rr_depth {
            survival = throughput.max_element().min(0.95);
            ends = survival <= 0.0 || rng.next_f32() >= survival;
        }
        let next = if ends {
            None
        } else {
            // The guide's choice number is drawn though nothing guides here: the one-path
            // loop draws it, and each path's numbers must be that loop's.
            let (_u_choice, u_lobe, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
            material.sample(shading, wo, u, u_lobe).and_then(|s| {
                if delta {
                    return Some((s.wi, s.weight, s.pdf));
                }
                let f = s.weight * s.pdf;
                if f == Vec3::ZERO {
                    return None;
                }
                let bsdf_pdf = material.pdf(shading, wo, s.wi);
                let pdf = self.mix_pdf(bsdf_pdf, None, 0.0);
                let mis_pdf = if settings.nee_weighs_guide { pdf } else { nee_partner_pdf(bsdf_pdf, 0.0, 0.0) };
                (pdf.is_finite() && pdf > 0.0).then(|| (s.wi, f / pdf, mis_pdf))
            })
        };
        if let Some(pending) = pending {
            light_samples.push(LaneLightSample { lane, pending, surface, cells: nee_cells, throughput });
        }
        match next.filter(|(_, factor, _)| factor.is_finite()) {
            Some((wi, factor, mis_pdf)) => {
                path.throughput = throughput / survival * factor;
                path.ray = Ray::new(self.spawn(point, geometric_normal, wi), wi);
                path.previous = Some((point, mis_pdf, delta, nee_cells));
                path.depth += 1;
            }
            None => path.done = true,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use guiding_core::{HemisphereGrid, HemisphereGridSettings};

    use super::*;
    use crate::integrator::IntegratorSettings;
    use crate::scene::Scene;
    use crate::scene_intersector::{IntersectorChoice, SceneIntersector};

    /// The repository's cornell box.
    fn cornell() -> Scene {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.json");
        Scene::from_json(&path, &std::fs::read_to_string(&path).unwrap()).unwrap()
    }

    /// The lane loop takes `nee` with lanes to spare, and leaves the one-path loop every
    /// path whose vertices need what it leaves out.
    #[test]
    fn nee_with_lanes_is_traced_in_lanes_and_guided_paths_are_not() {
        let scene = cornell();
        let intersector = SceneIntersector::build(&scene.triangles, IntersectorChoice::default()).unwrap();
        let tracer = |method, lanes| {
            let settings = IntegratorSettings { method, lanes, ..Default::default() };
            PathTracer::<'_, _, HemisphereGrid>::new(&scene, &intersector, settings)
        };
        assert!(tracer(Method::Nee, 16).traces_in_lanes());
        assert!(!tracer(Method::Nee, 1).traces_in_lanes());
        assert!(!tracer(Method::Pt, 16).traces_in_lanes());
        let settings = HemisphereGridSettings { probe_count: Some(8), ..Default::default() };
        let grid = HemisphereGrid::build(&scene.triangles, settings).unwrap();
        assert!(!tracer(Method::GuidedNee, 16).with_guide(Some(&grid)).traces_in_lanes());
    }

    /// Three lanes over 64 pixels: every pixel gets the radiance the one-path loop gives
    /// it from the same generator, and the counters add up alike.
    #[test]
    fn every_pixel_gets_its_own_path() {
        let scene = cornell();
        let scene = Scene { camera: scene.camera.with_resolution(8, 8), ..scene };
        let intersector = SceneIntersector::build(&scene.triangles, IntersectorChoice::default()).unwrap();
        let settings = IntegratorSettings { lanes: 3, ..Default::default() };
        let tracer = PathTracer::<'_, _, HemisphereGrid>::new(&scene, &intersector, settings);
        let pixels = 64;
        let mut out = vec![Vec3::splat(-1.0); pixels];
        let (mut scratch, mut records, mut counters) =
            (LaneScratch::default(), NeeRecords::default(), PathCounters::default());
        let rng_of = |i: usize| Pcg32::new(7, i as u64);
        let pixel_of = |i: usize| ((i % 8) as u32, (i / 8) as u32);
        tracer.radiance_in_lanes(&mut out, pixel_of, rng_of, &mut scratch, &mut records, &mut counters);
        assert_eq!(counters.paths, pixels as u64);
        // One path at a time, the same numbers.
        let mut path_scratch = Default::default();
        let mut alone = PathCounters::default();
        for (i, &radiance) in out.iter().enumerate() {
            let mut rng = rng_of(i);
            let (x, y) = pixel_of(i);
            let ray = tracer.camera_ray(x, y, &mut rng);
            assert_eq!(radiance, tracer.radiance(ray, None, &mut rng, &mut path_scratch, &mut alone), "pixel {i}");
        }
        assert_eq!(alone, counters, "the same rays, vertices and paths");
        assert!(out.iter().any(|r| r.max_element() > 0.0));
    }
}
