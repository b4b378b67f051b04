//! Camera paths traced in lanes: a thread keeps several paths in flight, traces all their
//! next rays as one batch ([`Intersector::intersect_many`]: Embree's 16-ray packets),
//! shades their vertices one lane after another (the same two parts as one path at a
//! time: [`super::vertex`]), and traces their light samples' shadow rays as another batch
//! ([`Intersector::occluded_many`]); a lane whose path ends takes the next pixel. It takes
//! the passes in which no path teaches as it goes (`pt` and `nee`, and the guided
//! methods' frozen passes: see [`PathTracer::traces_in_lanes`]).
//!
//! Each path draws from its own pixel's generator in the order a path traced alone does,
//! and adds its light in the same order, so the image is the one-path-at-a-time loop's
//! ([`PathTracer::radiance`]) to the last bit wherever the batch answers as single rays
//! do (both adapters do) and no light or environment guide learns from the light
//! samples (their records then come in another order: the same image within noise).
//!
//! On door 160×120 (Embree, 16 lanes) nee traces about 1.2× the paths/s of one path at a
//! time: the packets, and the lanes' independent vertices overlapping in the core.

use glam::Vec3;
use guiding_core::{Guide, Hit, Intersector, Pcg32, Ray};

use super::counters::{PathCounters, TIMED_PATH_STRIDE};
use super::direct::PendingLightSample;
use super::method::Method;
use super::tracer::{nee_partner_pdf, GuideClock, NeeCells, PathScratch, PathTracer, SurfaceInteraction};
use super::vertex::CameraPath;

/// A camera path in flight in a lane.
struct LanePath {
    /// Its pixel, as an index into the pixels being traced.
    pixel: usize,
    rng: Pcg32,
    path: CameraPath,
    /// Times its guide calls, where it is one of the timed paths.
    clock: GuideClock,
    /// Whether the path has ended (its light sample, if any, still to be added).
    done: bool,
}

/// A lane's light sample waiting for its shadow ray, with what adding it needs: the
/// vertex's next-event cells, scattering's density of the sample's direction (for MIS)
/// and the path's throughput there.
struct LaneLightSample {
    lane: usize,
    pending: PendingLightSample,
    cells: NeeCells,
    scatter_pdf: f32,
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
    /// Whether this pass's camera paths are traced in lanes: more than one lane, a
    /// camera path method (pt, nee, guided, guided-nee), and a pass in which nothing
    /// learns from a path as it goes (the guided methods' frozen passes; the light and
    /// environment guides learn from light samples, which the lanes teach too); no
    /// splitting, no opacity masks, and MIS with the BSDF's share of the mixture alone
    /// (`nee_weighs_guide` off).
    pub fn traces_in_lanes(&self) -> bool {
        let roles = self.pass_roles();
        let camera_paths =
            matches!(self.settings.method, Method::Pt | Method::Nee | Method::Guided | Method::GuidedNee);
        let splits = self.settings.splitting && self.roulette.is_some();
        let weighs_guide = self.settings.nee_weighs_guide && self.guide.is_some();
        self.settings.lanes > 1
            && camera_paths
            && !roles.learning
            && !roles.roulette_learns
            && !splits
            && !weighs_guide
            && !self.masks
    }

    /// The radiance of one camera path per pixel of `out` (its pixel (x, y) given by
    /// `pixel_of`, its generator by `rng_of`, what its pixel is expected to be by
    /// `estimate_of`), [`settings`](Self::settings)`.lanes` paths at a time; counters
    /// added to `counters`, the light and environment guides' records to `scratch`'s.
    pub fn radiance_in_lanes(
        &self,
        out: &mut [Vec3],
        pixel_of: impl Fn(usize) -> (u32, u32),
        rng_of: impl Fn(usize) -> Pcg32,
        estimate_of: impl Fn(usize) -> Option<f32>,
        scratch: &mut PathScratch<G::Region, G::Records>,
        counters: &mut PathCounters,
    ) {
        let mut lanes = std::mem::take(&mut scratch.lanes);
        self.trace_lanes(out, (pixel_of, rng_of, estimate_of), &mut lanes, scratch, counters);
        scratch.lanes = lanes;
    }

    fn trace_lanes(
        &self,
        out: &mut [Vec3],
        (pixel_of, rng_of, estimate_of): (
            impl Fn(usize) -> (u32, u32),
            impl Fn(usize) -> Pcg32,
            impl Fn(usize) -> Option<f32>,
        ),
        lanes: &mut LaneScratch,
        scratch: &mut PathScratch<G::Region, G::Records>,
        counters: &mut PathCounters,
    ) {
        let width = self.settings.lanes.max(1) as usize;
        let roles = self.pass_roles();
        let mut next_pixel = 0;
        let LaneScratch { paths, rays, hits, light_samples, shadow_rays, blocked } = lanes;
        paths.clear();
        loop {
            while paths.len() < width && next_pixel < out.len() {
                let mut rng = rng_of(next_pixel);
                let (x, y) = pixel_of(next_pixel);
                let ray = self.camera_ray(x, y, &mut rng);
                let clock =
                    GuideClock { enabled: self.guide.is_some() && counters.paths % TIMED_PATH_STRIDE == 0, nanos: 0 };
                counters.paths += 1;
                let path = CameraPath::new(ray, estimate_of(next_pixel));
                paths.push(LanePath { pixel: next_pixel, rng, path, clock, done: false });
                next_pixel += 1;
            }
            if paths.is_empty() {
                return;
            }
            rays.clear();
            rays.extend(paths.iter().map(|p| p.path.ray));
            hits.clear();
            hits.resize(rays.len(), None);
            counters.rays += rays.len() as u64;
            self.intersector.intersect_many(rays, hits);
            light_samples.clear();
            for (lane, (lane_path, hit)) in paths.iter_mut().zip(hits.iter()).enumerate() {
                let LanePath { rng, path, clock, done, .. } = lane_path;
                // The path's own clock times its guide calls (the scratch's is shared).
                std::mem::swap(clock, &mut scratch.clock);
                let next = hit.map(|hit| (hit, self.scene.material_at(hit.primitive, hit.barycentrics).0));
                let plan = self.arrive(path, next, roles, rng, scratch, counters);
                if let Some(plan) = &plan {
                    if roles.nee && !plan.delta && !path.reentering {
                        let records = (&mut scratch.clock, &mut scratch.nee_records);
                        let cells = plan.nee_cells;
                        if let Some(pending) = self.draw_light_sample(&plan.surface, cells, rng, records, counters) {
                            let SurfaceInteraction { wo, ref material, ref shading, .. } = plan.surface;
                            let guide_share = if plan.distribution.is_some() { plan.guide_share } else { 0.0 };
                            let bsdf_pdf = material.pdf(shading, wo, pending.wi);
                            let scatter_pdf = nee_partner_pdf(bsdf_pdf, guide_share, plan.focal_share);
                            let throughput = path.throughput;
                            light_samples.push(LaneLightSample { lane, pending, cells, scatter_pdf, throughput });
                        }
                    }
                }
                *done = !plan.is_some_and(|plan| self.scatter(path, &plan, roles, rng, scratch));
                std::mem::swap(clock, &mut scratch.clock);
            }
            shadow_rays.clear();
            shadow_rays.extend(light_samples.iter().map(|s| s.pending.ray));
            blocked.clear();
            blocked.resize(shadow_rays.len(), false);
            self.intersector.occluded_many(shadow_rays, blocked);
            for (sample, &blocked) in light_samples.iter().zip(blocked.iter()) {
                let transmittance = if blocked { 0.0 } else { 1.0 };
                let scatter_pdf = |_| sample.scatter_pdf;
                let records = &mut scratch.nee_records;
                let light =
                    self.finish_light_sample(&sample.pending, transmittance, sample.cells, scatter_pdf, records, 0);
                paths[sample.lane].path.radiance += sample.throughput * light;
            }
            // Ended paths give their lanes to the next pixels.
            let mut lane = 0;
            while lane < paths.len() {
                if paths[lane].done {
                    let LanePath { pixel, path, clock, .. } = paths.swap_remove(lane);
                    if path.radiance.max_element() > 0.0 {
                        counters.nonzero_paths += 1;
                    }
                    if clock.enabled {
                        counters.timed_paths += 1;
                        counters.timed_guide_nanos += clock.nanos;
                    }
                    out[pixel] = path.radiance;
                } else {
                    lane += 1;
                }
            }
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

    /// The lane loop takes the camera path methods' passes in which no path teaches as
    /// it goes, and leaves the others to the one-path loop.
    #[test]
    fn passes_that_learn_from_paths_are_not_traced_in_lanes() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.json");
        let scene = Scene::from_json(&path, &std::fs::read_to_string(&path).unwrap()).unwrap();
        let intersector = SceneIntersector::build(&scene.triangles, IntersectorChoice::default()).unwrap();
        let tracer = |method, lanes, learn| {
            let settings = IntegratorSettings { method, lanes, learn, ..Default::default() };
            PathTracer::<'_, _, HemisphereGrid>::new(&scene, &intersector, settings)
        };
        assert!(tracer(Method::Nee, 16, true).traces_in_lanes(), "nothing learns from nee's paths");
        assert!(tracer(Method::Pt, 16, true).traces_in_lanes());
        assert!(!tracer(Method::Nee, 1, true).traces_in_lanes());
        assert!(!tracer(Method::Bdpt, 16, false).traces_in_lanes());
        let settings = HemisphereGridSettings { probe_count: Some(8), ..Default::default() };
        let grid = HemisphereGrid::build(&scene.triangles, settings).unwrap();
        assert!(!tracer(Method::GuidedNee, 16, true).with_guide(Some(&grid)).traces_in_lanes(), "learning");
        assert!(tracer(Method::GuidedNee, 16, false).with_guide(Some(&grid)).traces_in_lanes(), "frozen");
        let weighs = IntegratorSettings { nee_weighs_guide: true, ..*tracer(Method::GuidedNee, 16, false).settings() };
        assert!(!tracer(Method::GuidedNee, 16, false).with_guide(Some(&grid)).with_settings(weighs).traces_in_lanes());
    }

    /// Three lanes over 64 pixels: every pixel gets the radiance the one-path loop gives
    /// it from the same generator, and the counters add up alike.
    #[test]
    fn every_pixel_gets_its_own_path() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.json");
        let scene = Scene::from_json(&path, &std::fs::read_to_string(&path).unwrap()).unwrap();
        let scene = Scene { camera: scene.camera.with_resolution(8, 8), ..scene };
        let intersector = SceneIntersector::build(&scene.triangles, IntersectorChoice::default()).unwrap();
        let settings = IntegratorSettings { lanes: 3, ..Default::default() };
        let tracer = PathTracer::<'_, _, HemisphereGrid>::new(&scene, &intersector, settings);
        let pixels = 64;
        let mut out = vec![Vec3::splat(-1.0); pixels];
        let (mut scratch, mut counters) = (PathScratch::default(), PathCounters::default());
        let rng_of = |i: usize| Pcg32::new(7, i as u64);
        let pixel_of = |i: usize| ((i % 8) as u32, (i / 8) as u32);
        tracer.radiance_in_lanes(&mut out, pixel_of, rng_of, |_| None, &mut scratch, &mut counters);
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
