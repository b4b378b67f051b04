//! Bidirectional path tracing (`bdpt`): per sample one camera subpath and one light
//! subpath, and every way of joining them — s vertices from the light, t from the camera
//! — evaluated. Each strategy is weighted by the power heuristic over all strategies
//! that could have made the same path, computed exactly from every vertex's forward
//! and reverse densities (Veach 1997, ch. 10, with pbrt-v3's ratio recursion). The
//! strategies with one camera vertex (t = 1) splat into the pixel they land in, as light
//! tracing does; s = 1 draws a fresh point on a light (next-event estimation); s = 0 is
//! a camera subpath that reaches an emitter.
//!
//! Lights are picked by power on both sides, whatever `--light-selection` says: the
//! light subpath's origin and next-event estimation must share one density for the
//! weights to be exact.

mod connect;
mod learn;
mod mis;
mod vertex;
mod vpl;
mod walk;

use glam::Vec3;
use guiding_core::{Guide, Intersector, PathRecorder, Pcg32};

use super::counters::PathCounters;
use super::tracer::PathTracer;
use crate::color::luminance;
use connect::Shadow;
pub use vertex::SubpathVertex;
pub use vpl::VirtualPointLights;

/// Per-thread space for the two subpaths (reused from sample to sample) and what the
/// camera subpath teaches the guide.
#[derive(Clone, Debug)]
pub struct BidirectionalScratch<R> {
    camera: Vec<SubpathVertex<R>>,
    light: Vec<SubpathVertex<R>>,
    /// Per camera vertex, the direct light its light sample (s = 1) reflects towards
    /// the previous vertex, MIS-weighted against scattering (luminance; learning only).
    direct: Vec<f32>,
    recorder: PathRecorder<R>,
    /// Per light vertex, the importance its camera connection (t = 1) reflects back
    /// towards the previous light vertex (luminance; learning W only).
    eye: Vec<f32>,
    light_recorder: PathRecorder<R>,
}

impl<R: Copy> Default for BidirectionalScratch<R> {
    fn default() -> Self {
        Self {
            camera: Vec::new(),
            light: Vec::new(),
            direct: Vec::new(),
            recorder: PathRecorder::new(),
            eye: Vec::new(),
            light_recorder: PathRecorder::new(),
        }
    }
}

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// One bidirectional sample for pixel (`x`, `y`): its camera strategies are added to
    /// `image` at that pixel, its light-tracing strategies (t = 1) where they land.
    /// Every entry of `image` is a contribution to its pixel's value, the light ones for
    /// as many light subpaths as pixels (one per sample).
    pub fn bidirectional_sample(
        &self,
        (x, y): (u32, u32),
        rng: &mut Pcg32,
        image: &mut [Vec3],
        scratch: &mut BidirectionalScratch<G::Region>,
        counters: &mut PathCounters,
    ) {
        counters.paths += 1;
        let BidirectionalScratch { camera, light, direct, recorder, eye, light_recorder } = scratch;
        self.camera_subpath(x, y, rng, camera, counters);
        self.light_subpath(rng, light, counters);
        let learning = self.settings.learn && self.guide.is_some();
        if learning {
            direct.clear();
            direct.resize(camera.len(), 0.0);
        }
        let learning_importance = self.settings.learn && self.importance.is_some();
        if learning_importance {
            eye.clear();
            eye.resize(light.len(), 0.0);
        }
        let width = self.scene.camera.width as usize;
        let pixel = y as usize * width + x as usize;
        let max_edges = self.settings.max_depth as usize;
        let threshold = self.connection_threshold;
        let mut contributed = false;
        for t in 1..=camera.len() {
            for s in 0..=light.len() {
                let edges = s + t - 1;
                if (t == 1 && s <= 1) || edges > max_edges {
                    continue;
                }
                let Some(mut connection) = self.connect(camera, light, s, t, rng) else { continue };
                let mut value = connection.value;
                if !(value.is_finite() && value.max_element() > 0.0) {
                    continue;
                }
                // Connection roulette: a faint connection has its shadow ray traced only
                // with probability ∝ its contribution (unweighted: an upper bound of the
                // weighted one, known before the weight's cost is paid), and counts by
                // the inverse (unbiased; most connections of a long path are faint).
                if threshold > 0.0 && connection.shadow != Shadow::Unblocked {
                    let survival = (luminance(value) / threshold).min(1.0);
                    if rng.next_f32() >= survival {
                        continue;
                    }
                    value /= survival;
                }
                value *= self.shadow_transmittance(&connection.shadow, counters);
                if value.max_element() <= 0.0 {
                    continue;
                }
                if let Some(sampled) = &mut connection.sampled {
                    // The weight reads W's density at the light point (bdpt-guided).
                    sampled.importance_region = self.emission_region(sampled.point, sampled.normal);
                }
                if learning && s == 1 {
                    if let Some(sampled) = &connection.sampled {
                        direct[t - 1] = self.learned_direct_light(camera, t, sampled, value);
                    }
                }
                if learning_importance && t == 1 {
                    eye[s - 1] = luminance(value) / luminance(light[s - 1].beta).max(f32::MIN_POSITIVE);
                }
                value *= self.mis_weight(camera, light, connection.sampled.as_ref(), s, t);
                if !(value.is_finite() && value.max_element() > 0.0) {
                    continue;
                }
                let index = connection.pixel.map_or(pixel, |(px, py)| py as usize * width + px as usize);
                image[index] += value;
                contributed = true;
            }
        }
        if contributed {
            counters.nonzero_paths += 1;
        }
        if learning {
            self.teach_camera_subpath(camera, direct, recorder);
        }
        if learning_importance {
            self.teach_light_subpath(light, eye, light_recorder);
        }
    }
}
