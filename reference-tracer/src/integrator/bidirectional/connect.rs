//! Joining a camera and a light subpath: each strategy's contribution before its
//! shadow ray, and the shadow ray's transmittance.

use glam::Vec3;
use guiding_core::{Guide, Intersector, Pcg32, Ray};

use super::vertex::{SubpathVertex, VertexKind};
use crate::camera::EyeConnection;
use crate::integrator::counters::PathCounters;
use crate::integrator::light_path::shading_correction;
use crate::integrator::tracer::PathTracer;

/// What is left to test of a connection: nothing (a camera subpath that reached an
/// emitter), the segment from a surface point to the eye, or one between two points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Shadow {
    Unblocked,
    Eye { point: Vec3, normal: Vec3, eye: EyeConnection },
    Segment { from: Vec3, normal: Vec3, to: Vec3 },
}

/// A strategy's contribution before its shadow ray.
pub(super) struct Connection<R> {
    /// Unweighted, as if nothing blocked it.
    pub(super) value: Vec3,
    /// The light vertex s = 1 drew.
    pub(super) sampled: Option<SubpathVertex<R>>,
    /// The pixel a t = 1 connection lands in.
    pub(super) pixel: Option<(u32, u32)>,
    pub(super) shadow: Shadow,
}

impl<R> Connection<R> {
    pub(super) fn unblocked(value: Vec3) -> Self {
        Self { value, sampled: None, pixel: None, shadow: Shadow::Unblocked }
    }
}

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// Strategy (s, t) before its shadow ray: the unweighted contribution if nothing
    /// blocks it, the light vertex it drew (s = 1), the pixel it lands in when that is
    /// not the sample's own (t = 1), and the segment left to test.
    pub(super) fn connect(
        &self,
        camera: &[SubpathVertex<G::Region>],
        light: &[SubpathVertex<G::Region>],
        s: usize,
        t: usize,
        rng: &mut Pcg32,
    ) -> Option<Connection<G::Region>> {
        if s == 0 {
            // The camera subpath reached an emitter.
            let pt = &camera[t - 1];
            let emitted = pt.emitted();
            let value = pt.beta * emitted;
            return (emitted.max_element() > 0.0).then_some(Connection::unblocked(value));
        }
        if t == 1 {
            // A light vertex seen by the camera.
            let qs = &light[s - 1];
            let (material, shading) = qs.surface.filter(|_| !qs.delta)?;
            let eye = self.scene.camera.connect(qs.point)?;
            let f = material.eval(&shading, qs.wo, eye.to_eye) * shading_correction(&shading, qs.wo, eye.to_eye);
            if f.max_element() <= 0.0 {
                return None;
            }
            let value = qs.beta * f * eye.importance;
            let shadow = Shadow::Eye { point: qs.point, normal: qs.normal, eye };
            return Some(Connection { value, sampled: None, pixel: Some(eye.pixel), shadow });
        }
        let pt = &camera[t - 1];
        let (camera_material, camera_shading) = pt.surface.filter(|_| !pt.delta)?;
        if s == 1 {
            // Next-event estimation: a fresh point on a light picked by power.
            let lights = &self.scene.lights;
            let (index, selection) = lights.select_by_power(rng.next_f32());
            let (_, emission, area) = lights.light(index);
            let (point, normal) = lights.emission_point(index, rng.next_vec2())?;
            let position_pdf = selection / area;
            let offset = point - pt.point;
            let distance2 = offset.length_squared();
            let wi = offset / distance2.sqrt();
            let cos_light = -normal.dot(wi);
            if !(position_pdf > 0.0 && cos_light > 0.0 && distance2 > 0.0) {
                return None;
            }
            let f = camera_material.eval(&camera_shading, pt.wo, wi);
            if f.max_element() <= 0.0 {
                return None;
            }
            let value = pt.beta * f * emission * (cos_light / (distance2 * position_pdf));
            let mut sampled =
                SubpathVertex::new(VertexKind::Light, point, normal, emission / position_pdf, position_pdf);
            sampled.light = Some(index);
            // W's region here is located only once the shadow ray passes (see
            // `bidirectional_sample`): most light samples are blocked.
            let shadow = Shadow::Segment { from: pt.point, normal: pt.normal, to: point };
            return Some(Connection { value, sampled: Some(sampled), pixel: None, shadow });
        }
        // Two surfaces joined by a shadow ray.
        let qs = &light[s - 1];
        let (light_material, light_shading) = qs.surface.filter(|_| !qs.delta)?;
        let offset = qs.point - pt.point;
        let distance2 = offset.length_squared();
        if !distance2.is_finite() || distance2 <= 0.0 {
            return None;
        }
        let wi = offset / distance2.sqrt();
        let f_camera = camera_material.eval(&camera_shading, pt.wo, wi);
        let f_light = light_material.eval(&light_shading, qs.wo, -wi) * shading_correction(&light_shading, qs.wo, -wi);
        if f_camera.max_element() <= 0.0 || f_light.max_element() <= 0.0 {
            return None;
        }
        let value = pt.beta * f_camera * f_light * qs.beta / distance2;
        let shadow = Shadow::Segment { from: pt.point, normal: pt.normal, to: qs.point };
        Some(Connection { value, sampled: None, pixel: None, shadow })
    }

    /// The share of light that passes `shadow` (masks weighed; 0 when blocked).
    pub(super) fn shadow_transmittance(&self, shadow: &Shadow, counters: &mut PathCounters) -> f32 {
        match shadow {
            Shadow::Unblocked => 1.0,
            Shadow::Eye { point, normal, eye } => self.eye_transmittance(*point, *normal, eye, counters),
            Shadow::Segment { from, normal, to } => self.segment_transmittance(*from, *normal, *to, counters),
        }
    }

    /// The share of light passing between `from` (on a surface of normal `normal`) and
    /// `to` (masks weighed; 0 when blocked), stopping short of both ends by the spawn
    /// offset.
    pub(super) fn segment_transmittance(&self, from: Vec3, normal: Vec3, to: Vec3, counters: &mut PathCounters) -> f32 {
        let offset = to - from;
        let distance = offset.length();
        let wi = offset / distance;
        let origin = self.spawn(from, normal, wi);
        let margin = self.epsilon_at(from) + self.epsilon_at(to);
        let t_max = (distance - margin).max(0.0) * (1.0 - 1e-5);
        counters.rays += 1;
        self.transmittance(Ray::segment(origin, wi, 0.0, t_max), counters)
    }
}
