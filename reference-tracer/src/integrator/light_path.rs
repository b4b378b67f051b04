//! Light tracing (`light`): a path starts on an area light and every vertex it reaches
//! connects to the camera, its contribution splatted into the pixel it projects into
//! (Veach's particle tracing, the bidirectional estimator with one camera vertex).

use glam::{Vec2, Vec3};
use guiding_core::{Guide, Intersector, Pcg32, Ray};

use super::counters::PathCounters;
use super::tracer::PathTracer;
use crate::camera::EyeConnection;
use crate::material::{Material, ShadingFrame, Surface};

/// Veach's correction of shading normals for light carried from `from` (towards the
/// previous vertex) to `to`: |from·n_s||to·n_g| / (|from·n_g||to·n_s|), which makes the
/// adjoint BSDF of a shading-normal frame transport importance as the forward one
/// transports radiance (1 where the shading normal is the geometric one).
fn shading_correction(shading: &ShadingFrame, from: Vec3, to: Vec3) -> f32 {
    let (ns, ng) = (shading.frame.normal, shading.geometric);
    let denominator = from.dot(ng).abs() * to.dot(ns).abs();
    if denominator <= 0.0 {
        return 0.0;
    }
    from.dot(ns).abs() * to.dot(ng).abs() / denominator
}

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// Traces one light path and adds each of its camera connections, as a contribution
    /// to the mean of the image (see [`EyeConnection::importance`]), to `splat` (one
    /// entry per pixel, row by row). A pixel's estimate is its entry times the pixel
    /// count over the light paths traced.
    pub fn light_path(&self, rng: &mut Pcg32, splat: &mut [Vec3], counters: &mut PathCounters) {
        let settings = &self.settings;
        let lights = &self.scene.lights;
        let camera = &self.scene.camera;
        counters.paths += 1;
        if lights.is_empty() {
            return;
        }
        let (light, selection) = lights.select_by_power(rng.next_f32());
        let (_, emission, area) = lights.light(light);
        let Some((origin, normal)) = lights.emission_point(light, rng.next_vec2()) else { return };
        let position_pdf = selection / area;
        if !(position_pdf > 0.0 && normal != Vec3::ZERO) {
            return;
        }
        let mut contributed = false;
        let mut add = |connection: &EyeConnection, value: Vec3| {
            if value.is_finite() && value.max_element() > 0.0 {
                let (x, y) = connection.pixel;
                splat[y as usize * camera.width as usize + x as usize] += value;
                contributed = true;
            }
        };
        // The light itself, seen by the camera.
        if let Some(connection) = camera.connect(origin) {
            let cos_light = normal.dot(connection.to_eye);
            if cos_light > 0.0 && self.sees_eye(origin, normal, &connection, counters) {
                add(&connection, emission * (cos_light * connection.importance / position_pdf));
            }
        }
        // Leave the light cosine-distributed about its normal: Le·cos/(p_A·cos/π).
        let local = cosine_direction(rng.next_vec2());
        let direction = guiding_core::Frame::from_normal(normal).to_world(local);
        let mut throughput = emission * (std::f32::consts::PI / position_pdf);
        // Russian roulette by the throughput relative to the light's own.
        let mut relative = Vec3::ONE;
        let mut ray = Ray::new(self.spawn(origin, normal, direction), direction);
        for depth in 0..settings.max_depth {
            counters.rays += 1;
            let Some((hit, material)) = self.next_surface(ray, rng, counters) else { break };
            counters.vertices += 1;
            let triangle = &self.scene.triangles[hit.primitive as usize];
            let point = triangle.point(hit.barycentrics);
            let geometric_normal = self.scene.normals[hit.primitive as usize];
            let shading_normal = self.scene.shading_normal(hit.primitive, hit.barycentrics);
            // Towards where the light came from.
            let from = -ray.direction;
            let shading = material.shading_frame(geometric_normal, shading_normal, from);
            if !material.is_delta() {
                if let Some(connection) = camera.connect(point) {
                    let f = material.eval(&shading, from, connection.to_eye)
                        * shading_correction(&shading, from, connection.to_eye);
                    if f.max_element() > 0.0 && self.sees_eye(point, geometric_normal, &connection, counters) {
                        add(&connection, throughput * f * connection.importance);
                    }
                }
            }
            if depth + 1 >= settings.max_depth {
                break;
            }
            if depth + 1 >= settings.rr_depth {
                let survival = relative.max_element().min(0.95);
                if survival <= 0.0 || rng.next_f32() >= survival {
                    break;
                }
                throughput /= survival;
                relative /= survival;
            }
            let (u, u_lobe) = (rng.next_vec2(), rng.next_f32());
            let Some(sample) = material.sample(&shading, from, u, u_lobe) else { break };
            let factor = importance_weight(&material, &shading, from, sample.wi, sample.weight);
            if !(factor.is_finite() && factor.max_element() > 0.0) {
                break;
            }
            throughput *= factor;
            relative *= factor;
            ray = Ray::new(self.spawn(point, geometric_normal, sample.wi), sample.wi);
        }
        if contributed {
            counters.nonzero_paths += 1;
        }
    }

    /// Whether nothing blocks the segment from `point` (on a surface of normal `normal`)
    /// to the eye.
    fn sees_eye(&self, point: Vec3, normal: Vec3, connection: &EyeConnection, counters: &mut PathCounters) -> bool {
        let origin = self.spawn(point, normal, connection.to_eye);
        let length = connection.distance - 2.0 * self.epsilon_at(point);
        if length <= 0.0 {
            return false;
        }
        counters.rays += 1;
        self.transmittance(Ray { t_max: length, ..Ray::new(origin, connection.to_eye) }, counters) > 0.0
    }
}

/// A sampled direction's factor in a light path: the BSDF sample's weight f·cos/pdf in
/// importance transport. Smooth refraction scales radiance by 1/η², but the power a
/// light path carries passes unscaled, so the refracted weight is 1 there; shading
/// normals get [`shading_correction`].
fn importance_weight(material: &Material, shading: &ShadingFrame, from: Vec3, to: Vec3, weight: Vec3) -> Vec3 {
    match material.surface {
        Surface::Dielectric { .. } => {
            let refracted = from.dot(shading.geometric) * to.dot(shading.geometric) < 0.0;
            if refracted {
                Vec3::ONE
            } else {
                weight
            }
        }
        Surface::ThinDielectric { .. } => weight,
        _ => weight * shading_correction(shading, from, to),
    }
}

/// A cosine-distributed direction about +z from two uniforms.
fn cosine_direction(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * std::f32::consts::PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt())
}
