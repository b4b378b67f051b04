//! What bdpt-guided's subpaths teach their guides: Q from the camera subpath, W from
//! the light subpath, both by Eq. (1) along the path's continuation.

use glam::Vec3;
use guiding_core::{Guide, Intersector, PathRecorder};

use super::vertex::{Side, SubpathVertex};
use crate::color::luminance;
use crate::integrator::tracer::PathTracer;

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// The light sample of camera vertex t − 1 (its contribution `value`, unweighted,
    /// from the light point `sampled`) as the radiance it reflects towards the previous
    /// vertex, weighted by the power heuristic against the camera side's sampling finding
    /// the same light (luminance): with that weight on the emission scattering finds, the
    /// two add up to the light arriving there, as path tracing with next-event
    /// estimation estimates it.
    pub(super) fn learned_direct_light(
        &self,
        camera: &[SubpathVertex<G::Region>],
        t: usize,
        sampled: &SubpathVertex<G::Region>,
        value: Vec3,
    ) -> f32 {
        let pt = &camera[t - 1];
        let scatter = self.density_towards(pt, t.checked_sub(2).map(|i| &camera[i]), sampled, Side::Camera);
        let light = sampled.pdf_fwd;
        let weight = crate::sampling::power_heuristic(light, scatter);
        luminance(value) * weight / luminance(pt.beta).max(f32::MIN_POSITIVE)
    }

    /// Teaches the guide what the camera subpath found (bdpt-guided, learning passes):
    /// Eq. (1) along it, by the path's own continuation, each vertex's target the
    /// emission its direction reached (weighted against light sampling, the rest learned
    /// by the vertex alone, as `nee_kickstart` does) plus the direct light the next
    /// vertex's light sample reflects back, plus what the next vertex's own target
    /// carries back.
    pub(super) fn teach_camera_subpath(
        &self,
        camera: &[SubpathVertex<G::Region>],
        direct: &[f32],
        recorder: &mut PathRecorder<G::Region>,
    ) {
        let Some(guide) = self.guide else { return };
        recorder.clear();
        for k in 1..camera.len() {
            let vertex = &camera[k];
            if k >= 2 {
                // What arrived along the direction camera[k − 1] scattered.
                let from = &camera[k - 1];
                let emitted = luminance(vertex.emitted());
                if emitted > 0.0 {
                    // Area densities at this vertex of both strategies that find it.
                    let light = self.light_origin_pdf(vertex);
                    let weight = if from.delta { 1.0 } else { crate::sampling::power_heuristic(vertex.pdf_fwd, light) };
                    recorder.arrive(weight * emitted);
                    recorder.arrive_learned_only((1.0 - weight) * emitted);
                    // The light's density per steradian, as seen from the scattering vertex.
                    let offset = vertex.point - from.point;
                    let cos = vertex.normal.dot(offset).abs() / offset.length();
                    if cos > 0.0 && !from.delta {
                        recorder.add_density(light * offset.length_squared() / cos);
                    }
                }
                recorder.arrive(direct[k]);
                carry_back(recorder, camera, k);
            }
            record_scattering(recorder, camera, k, vertex.region);
        }
        recorder.learn(guide, self.settings.density_weighted_learning);
    }

    /// Teaches W what the light subpath found (bdpt-guided, learning passes): Eq. (1)
    /// with the roles swapped, as `light-guided` learns it. Each vertex's target is the
    /// importance the next vertex's camera connection reflects back, plus the next
    /// vertex's own target carried back by its scattering factor.
    pub(super) fn teach_light_subpath(
        &self,
        light: &[SubpathVertex<G::Region>],
        eye: &[f32],
        recorder: &mut PathRecorder<G::Region>,
    ) {
        let Some(importance) = self.importance else { return };
        recorder.clear();
        for j in 0..light.len() {
            let vertex = &light[j];
            if j >= 1 {
                recorder.arrive(eye[j]);
                carry_back(recorder, light, j);
            }
            record_scattering(recorder, light, j, vertex.importance_region);
        }
        recorder.learn(importance, self.settings.density_weighted_learning);
    }
}

/// Vertex `k` of `path` passes its own target back to the vertex before it, scaled by
/// its scattering factor (the throughput's ratio, 1/survival included), where it
/// scattered on.
fn carry_back<R: Copy>(recorder: &mut PathRecorder<R>, path: &[SubpathVertex<R>], k: usize) {
    if let Some(next) = path.get(k + 1) {
        recorder.carry(luminance(next.beta) / luminance(path[k].beta).max(f32::MIN_POSITIVE));
    }
}

/// Records vertex `k` of `path` as scattering towards vertex k + 1 (where there is one),
/// learning in `region` unless it scattered by a delta lobe.
fn record_scattering<R: Copy>(recorder: &mut PathRecorder<R>, path: &[SubpathVertex<R>], k: usize, region: Option<R>) {
    let (vertex, Some(next)) = (&path[k], path.get(k + 1)) else { return };
    let offset = next.point - vertex.point;
    let distance = offset.length();
    let region = region.filter(|_| !vertex.delta);
    recorder.scattered(region, vertex.point, offset / distance, vertex.scatter_pdf, luminance(next.beta), ());
    recorder.reached(distance);
}
