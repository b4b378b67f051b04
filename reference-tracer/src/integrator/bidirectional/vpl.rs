//! Instant radiosity (`vpl`, Keller 1997): per pass a few light subpaths are traced and
//! every vertex where light could scatter on (a point on a light, a surface that is not
//! all delta) becomes a virtual point light; each camera ray's first surface that is not
//! all delta gathers from every one of them through a shadow ray.
//!
//! The gather's geometry term is clamped: 1/d² is taken at no less than the minimum
//! distance `d_min` (`--vpl-min-distance` times the scene's extent), which removes the
//! bright splotches next to each virtual light at the price of a bias: light exchanged
//! between points closer than `d_min` (corners, contact shadows) comes out darker than
//! it is. Light that reaches the eye only through mirrors or glass after the gathering
//! surface is left out as well (the gather ends at the first surface that is not all
//! delta). The estimate is therefore biased; `nee` and `bdpt` are the unbiased
//! references. What it buys is coherence: with the same random numbers every pass and
//! frame the virtual lights do not move, so an animation does not flicker.
//!
//! `vpl-guided` draws the light subpaths' directions from W too (with probability
//! p_guide, as bdpt-guided's light side does) and, in learning passes, teaches W what
//! each virtual light gave the image: Eq. (1) with the roles swapped, each vertex's
//! target the image's gain from the next vertex's virtual light per unit of its power,
//! plus that vertex's own target carried back.

use glam::Vec3;
use guiding_core::{Guide, Intersector, PathRecorder, Pcg32, Ray};

use super::vertex::{SubpathVertex, VertexKind};
use crate::color::luminance;
use crate::integrator::counters::PathCounters;
use crate::integrator::light_path::shading_correction;
use crate::integrator::tracer::PathTracer;

/// The virtual point lights of one pass: the vertices of its light subpaths, each
/// carrying its share of the lights' power.
#[derive(Clone, Debug)]
pub struct VirtualPointLights<R> {
    /// Every vertex of every light subpath, path after path (delta vertices too, for
    /// learning), each power weight divided by the subpath count.
    vertices: Vec<SubpathVertex<R>>,
    /// Where each subpath starts in `vertices`, and its end.
    starts: Vec<usize>,
    /// The vertices that are virtual lights.
    lights: Vec<u32>,
}

impl<R> VirtualPointLights<R> {
    /// Per vertex of the subpaths, a tally to add what each virtual light gives the
    /// image into (vpl-guided's learning passes).
    pub fn tally(&self) -> Vec<f32> {
        vec![0.0; self.vertices.len()]
    }
}

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// `paths` light subpaths drawn with `rng` (unguided), their vertices kept as virtual
    /// point lights, each vertex's power weight divided by `paths`.
    pub fn virtual_point_lights(
        &self,
        paths: u32,
        rng: &mut Pcg32,
        counters: &mut PathCounters,
    ) -> VirtualPointLights<G::Region> {
        let (mut vertices, mut starts, mut lights) = (Vec::new(), vec![0], Vec::new());
        let mut path = Vec::new();
        let share = 1.0 / paths.max(1) as f32;
        for _ in 0..paths {
            self.light_subpath(rng, &mut path, counters);
            for vertex in &path {
                let keeps = match vertex.kind {
                    VertexKind::Light => true,
                    VertexKind::Surface => !vertex.delta && vertex.surface.is_some(),
                    VertexKind::Camera => false,
                };
                if keeps && vertex.beta.max_element() > 0.0 && vertex.beta.is_finite() {
                    lights.push(vertices.len() as u32);
                }
                vertices.push(SubpathVertex { beta: vertex.beta * share, ..*vertex });
            }
            starts.push(vertices.len());
        }
        VirtualPointLights { vertices, starts, lights }
    }

    /// Teaches W what the virtual lights gave the image (vpl-guided, learning passes):
    /// `tally` holds, per vertex, the luminance its virtual light added over all `pixels`
    /// pixels ([`gather`](Self::gather)); per unit of the vertex's power weight that is
    /// the importance arriving along the direction that reached it.
    pub fn teach_virtual_lights(
        &self,
        vpls: &VirtualPointLights<G::Region>,
        tally: &[f32],
        pixels: usize,
        recorder: &mut PathRecorder<G::Region>,
    ) {
        if self.importance.is_none() || !self.settings.learn {
            return;
        }
        let mut eye = Vec::new();
        for range in vpls.starts.windows(2) {
            let path = &vpls.vertices[range[0]..range[1]];
            eye.clear();
            eye.extend(path.iter().zip(&tally[range[0]..range[1]]).map(|(vertex, &sum)| {
                let power = luminance(vertex.beta);
                if power > 0.0 {
                    sum / (pixels.max(1) as f32 * power)
                } else {
                    0.0
                }
            }));
            self.teach_light_subpath(path, &eye, recorder);
        }
    }

    /// Radiance arriving along the camera ray `ray`: emission seen directly (through
    /// mirrors and glass too) plus, at the first surface that is not all delta, the
    /// light of every virtual point light in `vpls` that it sees, 1/d² clamped at
    /// `min_distance` (scene units). With a `tally` (one entry per vertex of the
    /// subpaths), each light's luminance here is added to its entry.
    pub fn gather(
        &self,
        mut ray: Ray,
        vpls: &VirtualPointLights<G::Region>,
        min_distance: f32,
        rng: &mut Pcg32,
        counters: &mut PathCounters,
        mut tally: Option<&mut [f32]>,
    ) -> Vec3 {
        let (mut throughput, mut radiance) = (Vec3::ONE, Vec3::ZERO);
        let min_distance2 = min_distance * min_distance;
        counters.paths += 1;
        for _ in 0..self.settings.max_depth {
            counters.rays += 1;
            let Some((hit, material)) = self.next_surface(ray, rng, counters) else {
                return radiance;
            };
            counters.vertices += 1;
            let surface = self.interaction(&hit, material, ray.direction);
            if surface.material.is_emissive() && surface.geometric_normal.dot(surface.wo) > 0.0 {
                radiance += throughput * surface.material.emission;
            }
            if surface.material.is_delta() {
                let Some(s) = surface.material.sample(&surface.shading, surface.wo, rng.next_vec2(), rng.next_f32())
                else {
                    return radiance;
                };
                throughput *= s.weight;
                if !(throughput.is_finite() && throughput.max_element() > 0.0) {
                    return radiance;
                }
                ray = Ray::new(self.spawn(surface.point, surface.geometric_normal, s.wi), s.wi);
                continue;
            }
            for &index in &vpls.lights {
                let light = &vpls.vertices[index as usize];
                let offset = light.point - surface.point;
                let distance2 = offset.length_squared();
                if !(distance2.is_finite() && distance2 > 0.0) {
                    continue;
                }
                let wi = offset / distance2.sqrt();
                let f = surface.material.eval(&surface.shading, surface.wo, wi);
                if f.max_element() <= 0.0 {
                    continue;
                }
                // What leaves the virtual light towards the surface, per unit of its power
                // weight: the emitter's cosine, or the BSDF there (f·cos) seen from the light.
                let leaving = match (light.kind, light.surface) {
                    (VertexKind::Light, _) => Vec3::splat((-light.normal.dot(wi)).max(0.0)),
                    (_, Some((material, shading))) => {
                        material.eval(&shading, light.wo, -wi) * shading_correction(&shading, light.wo, -wi)
                    }
                    _ => Vec3::ZERO,
                };
                let value = throughput * f * leaving * light.beta / distance2.max(min_distance2);
                if value.max_element() <= 0.0 || !value.is_finite() {
                    continue;
                }
                let passed = self.segment_transmittance(surface.point, surface.geometric_normal, light.point, counters);
                radiance += value * passed;
                if let Some(tally) = tally.as_deref_mut() {
                    tally[index as usize] += luminance(value) * passed;
                }
            }
            if radiance.max_element() > 0.0 {
                counters.nonzero_paths += 1;
            }
            return radiance;
        }
        radiance
    }
}
