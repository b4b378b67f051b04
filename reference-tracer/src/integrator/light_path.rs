//! Light tracing (`light`): a path starts on an area light and every vertex it reaches
//! connects to the camera, its contribution splatted into the pixel it projects into
//! (Veach's particle tracing, the bidirectional estimator with one camera vertex).
//! `light-guided` draws each direction, the first one leaving the light included, from
//! the BSDF (or the light's cosine) or, with probability p_guide, from the directional
//! guide, weighted by the one-sample mixture's pdf; there the guide holds W, the
//! importance a direction carries to the camera, learned from the light paths by
//! Eq. (1) with the roles swapped: what arrives along a direction is the importance its
//! next vertex's camera connection reflects back, plus (the path's own continuation)
//! that vertex's target times its scattering factor.

use glam::{Vec2, Vec3};
use guiding_core::{DirectionalDistribution, Frame, Guide, Intersector, PathRecorder, Pcg32, Ray};

use super::counters::PathCounters;
use super::tracer::{PathTracer, SurfaceInteraction};
use crate::camera::EyeConnection;
use crate::color::luminance;
use crate::material::{Material, ShadingFrame, Surface};

/// The start of a light path.
#[derive(Clone, Copy, Debug)]
pub(super) struct LightOrigin {
    /// The light's index.
    pub(super) light: u32,
    /// Its emitted radiance.
    pub(super) emission: Vec3,
    /// The point on it.
    pub(super) point: Vec3,
    /// Its front normal there.
    pub(super) normal: Vec3,
    /// Density of the point per unit area, the light's selection included.
    pub(super) position_pdf: f32,
}

/// Veach's correction of shading normals for light carried from `from` (towards the
/// previous vertex) to `to`: |from·n_s||to·n_g| / (|from·n_g||to·n_s|), which makes the
/// adjoint BSDF of a shading-normal frame transport importance as the forward one
/// transports radiance (1 where the shading normal is the geometric one).
pub(super) fn shading_correction(shading: &ShadingFrame, from: Vec3, to: Vec3) -> f32 {
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
    pub fn light_path(
        &self,
        rng: &mut Pcg32,
        splat: &mut [Vec3],
        path: &mut PathRecorder<G::Region>,
        counters: &mut PathCounters,
    ) {
        let settings = &self.settings;
        let learning = settings.learn && self.guide.is_some();
        let p_guide = if self.guide.is_some() { settings.guide_probability } else { 0.0 };
        path.clear();
        let camera = &self.scene.camera;
        counters.paths += 1;
        let Some(LightOrigin { emission, point: origin, normal, position_pdf, .. }) = self.light_origin(rng) else {
            return;
        };
        let width = camera.width as usize;
        let mut contributed = false;
        // The light itself, seen by the camera.
        if let Some(connection) = camera.connect(origin) {
            let cos_light = normal.dot(connection.to_eye);
            let visible =
                if cos_light > 0.0 { self.eye_transmittance(origin, normal, &connection, counters) } else { 0.0 };
            if visible > 0.0 {
                let value = emission * (cos_light * visible * connection.importance / position_pdf);
                contributed |= splat_into(splat, width, &connection, value);
            }
        }
        // Leave the light by the cosine about its normal, or by W: Le·cos/(p_A·p(ω)).
        let region = self.guide.and_then(|guide| guide.locate(origin, normal));
        let distribution = match (self.guide, region) {
            (Some(guide), Some(region)) => Some(guide.distribution(region)),
            _ => None,
        };
        let frame = Frame::from_normal(normal);
        let (u_choice, u) = (rng.next_f32(), rng.next_vec2());
        let direction = match &distribution {
            Some(d) if u_choice < p_guide => d.sample(u).direction,
            _ => frame.to_world(cosine_direction(u)),
        };
        let cos_light = direction.dot(normal);
        let cosine_pdf = cos_light.max(0.0) * std::f32::consts::FRAC_1_PI;
        let pdf = match &distribution {
            Some(d) => p_guide * d.pdf(direction) + (1.0 - p_guide) * cosine_pdf,
            None => cosine_pdf,
        };
        if !(cos_light > 0.0 && pdf > 0.0) {
            self.finish_light_path(path, contributed, counters);
            return;
        }
        let mut throughput = emission * (cos_light / (position_pdf * pdf));
        // Russian roulette by the throughput relative to the light's own (what leaving
        // by the cosine would give).
        let mut relative = Vec3::splat(cosine_pdf / pdf);
        let mut ray = Ray::new(self.spawn(origin, normal, direction), direction);
        if learning {
            path.scattered(region, origin, direction, pdf, luminance(throughput), ());
        }
        for depth in 0..settings.max_depth {
            counters.rays += 1;
            let Some((hit, material)) = self.next_surface(ray, rng, counters) else { break };
            counters.vertices += 1;
            // `from` points towards where the light came from.
            let surface = self.interaction(&hit, material, ray.direction);
            let SurfaceInteraction { point, geometric_normal, wo: from, ref material, ref shading } = surface;
            if !material.is_delta() {
                if let Some(connection) = camera.connect(point) {
                    let f = material.eval(shading, from, connection.to_eye)
                        * shading_correction(shading, from, connection.to_eye);
                    let visible = if f.max_element() > 0.0 {
                        self.eye_transmittance(point, geometric_normal, &connection, counters)
                    } else {
                        0.0
                    };
                    if visible > 0.0 {
                        let importance = visible * connection.importance;
                        contributed |= splat_into(splat, width, &connection, throughput * f * importance);
                        if learning {
                            path.arrive(luminance(f) * importance);
                        }
                    }
                }
            }
            if depth + 1 >= settings.max_depth {
                break;
            }
            let mut survival = 1.0;
            if depth + 1 >= settings.rr_depth {
                survival = relative.max_element().min(0.95);
                if survival <= 0.0 || rng.next_f32() >= survival {
                    break;
                }
                throughput /= survival;
                relative /= survival;
            }
            let (u_choice, u, u_lobe) = (rng.next_f32(), rng.next_vec2(), rng.next_f32());
            let delta = material.is_delta();
            let region = match self.guide {
                Some(guide) if !delta => guide.locate(point, shading.frame.normal),
                _ => None,
            };
            let distribution = match (self.guide, region) {
                (Some(guide), Some(region)) => Some(guide.distribution(region)),
                _ => None,
            };
            let scattering = Scattering { material, shading, wo: from, importance: true };
            let Some((to, factor, pdf)) = scattering.sample(distribution.as_ref(), p_guide, (u_choice, u, u_lobe))
            else {
                break;
            };
            if !(factor.is_finite() && factor.max_element() > 0.0 && pdf > 0.0) {
                break;
            }
            throughput *= factor;
            relative *= factor;
            if learning {
                // The vertex before passes this one's target back, times its factor.
                path.carry(luminance(factor) / survival);
                path.scattered(region, point, to, pdf, luminance(throughput), ());
            }
            ray = Ray::new(self.spawn(point, geometric_normal, to), to);
        }
        self.finish_light_path(path, contributed, counters);
    }

    /// Where a light path starts: a light picked by power, a point uniform on it (`None`
    /// where the scene has no light or the point no density or normal).
    pub(super) fn light_origin(&self, rng: &mut Pcg32) -> Option<LightOrigin> {
        let lights = &self.scene.lights;
        if lights.is_empty() {
            return None;
        }
        let (light, selection) = lights.select_by_power(rng.next_f32());
        let (_, emission, area) = lights.light(light);
        let (point, normal) = lights.emission_point(light, rng.next_vec2())?;
        let position_pdf = selection / area;
        (position_pdf > 0.0 && normal != Vec3::ZERO).then_some(LightOrigin {
            light,
            emission,
            point,
            normal,
            position_pdf,
        })
    }

    /// Counts a finished light path and teaches its targets to the guide (when learning).
    fn finish_light_path(&self, path: &PathRecorder<G::Region>, contributed: bool, counters: &mut PathCounters) {
        if contributed {
            counters.nonzero_paths += 1;
        }
        if let (true, Some(guide)) = (self.settings.learn, self.guide) {
            path.learn(guide, self.settings.density_weighted_learning);
        }
    }

    /// The share of light that passes from `point` (on a surface of normal `normal`) to the
    /// eye: 0 when something opaque blocks it, else the product of the masked surfaces'
    /// 1 − opacity on the way (as a light sample's shadow ray counts them).
    pub(super) fn eye_transmittance(
        &self,
        point: Vec3,
        normal: Vec3,
        connection: &EyeConnection,
        counters: &mut PathCounters,
    ) -> f32 {
        let origin = self.spawn(point, normal, connection.to_eye);
        let length = connection.distance - 2.0 * self.epsilon_at(point);
        if length <= 0.0 {
            return 0.0;
        }
        counters.rays += 1;
        self.transmittance(Ray { t_max: length, ..Ray::new(origin, connection.to_eye) }, counters)
    }
}

/// A sampled direction's factor in a light path: the BSDF sample's weight f·cos/pdf in
/// importance transport. Smooth refraction scales radiance by 1/η², but the power a
/// light path carries passes unscaled, so the refracted weight is 1 there; shading
/// normals get [`shading_correction`].
pub(super) fn importance_weight(
    material: &Material,
    shading: &ShadingFrame,
    from: Vec3,
    to: Vec3,
    weight: Vec3,
) -> Vec3 {
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

/// A surface scattering a path that arrived from `wo`, in radiance transport or (with
/// `importance`) in importance transport, for [`sample`](Self::sample).
pub(super) struct Scattering<'a> {
    pub(super) material: &'a Material,
    pub(super) shading: &'a ShadingFrame,
    pub(super) wo: Vec3,
    pub(super) importance: bool,
}

impl Scattering<'_> {
    /// A direction from the one-sample mixture of `distribution` (probability
    /// `p_guide`) and the BSDF, with its factor f·cos/pdf (importance transport: the
    /// adjoint shading-normal correction, refraction unscaled) and the mixture's pdf per
    /// steradian; `None` where the BSDF draws nothing.
    pub(super) fn sample<D: DirectionalDistribution>(
        &self,
        distribution: Option<&D>,
        p_guide: f32,
        (u_choice, u, u_lobe): (f32, Vec2, f32),
    ) -> Option<(Vec3, Vec3, f32)> {
        let Scattering { material, shading, wo, importance } = *self;
        let Some(d) = distribution else {
            let sample = material.sample(shading, wo, u, u_lobe)?;
            let factor = if importance {
                importance_weight(material, shading, wo, sample.wi, sample.weight)
            } else {
                sample.weight
            };
            return Some((sample.wi, factor, sample.pdf));
        };
        let wi = if u_choice < p_guide { d.sample(u).direction } else { material.sample(shading, wo, u, u_lobe)?.wi };
        let pdf = p_guide * d.pdf(wi) + (1.0 - p_guide) * material.pdf(shading, wo, wi);
        let mut f = material.eval(shading, wo, wi);
        if importance {
            f *= shading_correction(shading, wo, wi);
        }
        Some((wi, f / pdf, pdf))
    }
}

/// Adds `value` to the pixel `connection` lands in; whether it added anything.
fn splat_into(splat: &mut [Vec3], width: usize, connection: &EyeConnection, value: Vec3) -> bool {
    if !(value.is_finite() && value.max_element() > 0.0) {
        return false;
    }
    let (x, y) = connection.pixel;
    splat[y as usize * width + x as usize] += value;
    true
}

/// A cosine-distributed direction about +z from two uniforms.
pub(super) fn cosine_direction(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * std::f32::consts::PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt())
}
