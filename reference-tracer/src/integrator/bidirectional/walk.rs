//! The two subpaths: from the camera and from a light, each by BSDF sampling or, in
//! bdpt-guided, mixed with its side's guide (Q from the camera, W from the light).

use glam::Vec3;
use guiding_core::{DirectionalDistribution, Frame, Guide, Intersector, Pcg32, Ray};

use super::vertex::{Side, SubpathVertex, VertexKind};
use crate::integrator::counters::PathCounters;
use crate::integrator::light_path::{cosine_direction, LightOrigin, Scattering};
use crate::integrator::tracer::PathTracer;

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// The camera subpath through pixel (`x`, `y`): the eye, then up to `max_depth`
    /// surfaces.
    pub(super) fn camera_subpath(
        &self,
        x: u32,
        y: u32,
        rng: &mut Pcg32,
        path: &mut Vec<SubpathVertex<G::Region>>,
        counters: &mut PathCounters,
    ) {
        path.clear();
        let ray = self.camera_ray(x, y, rng);
        let camera = &self.scene.camera;
        let (_, forward, ..) = camera.basis();
        path.push(SubpathVertex::new(VertexKind::Camera, ray.origin, forward, Vec3::ONE, 1.0));
        self.random_walk(ray, Vec3::ONE, Side::Camera, rng, path, counters);
    }

    /// The light subpath: a point on a light picked by power, uniform on it, leaving by
    /// the cosine about its normal; then up to `max_depth − 1` surfaces.
    pub(super) fn light_subpath(
        &self,
        rng: &mut Pcg32,
        path: &mut Vec<SubpathVertex<G::Region>>,
        counters: &mut PathCounters,
    ) {
        path.clear();
        let Some(LightOrigin { light, emission, point: origin, normal, position_pdf }) = self.light_origin(rng) else {
            return;
        };
        let mut start = SubpathVertex::new(VertexKind::Light, origin, normal, emission / position_pdf, position_pdf);
        start.light = Some(light);
        start.importance_region = self.emission_region(origin, normal);
        // Leave by the cosine about the normal or, in bdpt-guided, by W.
        let p_guide = self.guide_share(Side::Light);
        let distribution = match (self.importance, start.importance_region) {
            (Some(importance), Some(region)) if p_guide > 0.0 => Some(importance.distribution(region)),
            _ => None,
        };
        let (u_choice, u) = (rng.next_f32(), rng.next_vec2());
        let direction = match &distribution {
            Some(d) if u_choice < p_guide => d.sample(u).direction,
            _ => Frame::from_normal(normal).to_world(cosine_direction(u)),
        };
        let cos_light = direction.dot(normal);
        let pdf_dir = self.emission_direction_pdf(&start, direction);
        if !(cos_light > 0.0 && pdf_dir > 0.0) {
            path.push(start);
            return;
        }
        start.scatter_pdf = pdf_dir;
        path.push(start);
        let beta = emission * (cos_light / (position_pdf * pdf_dir));
        let ray = Ray::new(self.spawn(origin, normal, direction), direction);
        self.random_walk(ray, beta, Side::Light, rng, path, counters);
    }

    /// Extends `path` (which holds its first vertex) along `ray`, up to `max_depth` + 1
    /// vertices from the camera and `max_depth` from a light (so that no strategy makes a
    /// path of more than `max_depth` segments), recording each vertex's forward density
    /// and its predecessor's reverse one. From the light (`Side::Light`) it carries
    /// importance (adjoint shading-normal correction, refraction unscaled) and samples
    /// the BSDF; from the camera it samples the BSDF or, in bdpt-guided, with probability
    /// p_guide the guide, weighted by the mixture's density.
    ///
    /// Both densities are evaluated between the vertices where they lie, not taken from
    /// the sampler: a ray leaves its surface from a point offset along the normal, so the
    /// sampled direction differs slightly from the one between the vertices, and only
    /// densities of the same geometry make the strategies' weights sum to one exactly.
    pub(super) fn random_walk(
        &self,
        mut ray: Ray,
        mut beta: Vec3,
        side: Side,
        rng: &mut Pcg32,
        path: &mut Vec<SubpathVertex<G::Region>>,
        counters: &mut PathCounters,
    ) {
        let max_vertices = self.settings.max_depth as usize + usize::from(side == Side::Camera);
        let p_guide = self.guide_share(side);
        // Russian roulette by the throughput relative to the subpath's start.
        let mut relative = Vec3::ONE;
        while path.len() < max_vertices {
            counters.rays += 1;
            let Some((hit, material)) = self.next_surface(ray, rng, counters) else { break };
            counters.vertices += 1;
            let surface = self.interaction(&hit, material, ray.direction);
            let mut vertex =
                SubpathVertex::new(VertexKind::Surface, surface.point, surface.geometric_normal, beta, 0.0);
            vertex.wo = surface.wo;
            vertex.surface = Some((surface.material, surface.shading));
            vertex.delta = surface.material.is_delta();
            if surface.material.is_emissive() {
                vertex.light = self.scene.lights.light_at(hit.primitive, hit.barycentrics);
            }
            // Both sides locate in both guides: a vertex's density for the other side's
            // sampling needs that side's region.
            if !vertex.delta {
                let normal = surface.shading.frame.normal;
                vertex.region = self.guide.and_then(|guide| guide.locate(surface.point, normal));
                vertex.importance_region = if self.shared_regions {
                    vertex.region
                } else {
                    self.importance.and_then(|w| w.locate(surface.point, normal))
                };
            }
            let k = path.len();
            let previous = path[k - 1];
            vertex.back_guide_pdf = self.guide_density_towards(&vertex, &previous, side.other());
            if !previous.delta {
                let before = k.checked_sub(2).map(|i| path[i]);
                vertex.pdf_fwd = self.density_towards(&previous, before.as_ref(), &vertex, side);
                if let Some(before) = before {
                    path[k - 2].pdf_rev = self.density_back(&previous, Some(&vertex), &before, side.other());
                }
            }
            path.push(vertex);
            if path.len() >= max_vertices {
                break;
            }
            if path.len() > self.settings.rr_depth as usize {
                let survival = relative.max_element().min(0.95);
                if survival <= 0.0 || rng.next_f32() >= survival {
                    break;
                }
                beta /= survival;
                relative /= survival;
            }
            let (u_choice, u, u_lobe) = (rng.next_f32(), rng.next_vec2(), rng.next_f32());
            let (material, shading, wo) = (&surface.material, &surface.shading, surface.wo);
            let (guide, region) = match side {
                Side::Camera => (self.guide, vertex.region),
                Side::Light => (self.importance, vertex.importance_region),
            };
            let distribution = match (guide, region) {
                (Some(guide), Some(region)) if p_guide > 0.0 => Some(guide.distribution(region)),
                _ => None,
            };
            let scattering = Scattering { material, shading, wo, importance: side == Side::Light };
            let Some((wi, factor, pdf)) = scattering.sample(distribution.as_ref(), p_guide, (u_choice, u, u_lobe))
            else {
                break;
            };
            if !(factor.is_finite() && factor.max_element() > 0.0 && pdf > 0.0) {
                break;
            }
            beta *= factor;
            relative *= factor;
            path[k].scatter_pdf = pdf;
            ray = Ray::new(self.spawn(surface.point, surface.geometric_normal, wi), wi);
        }
    }

    /// bdpt-guided's share of the guide in `side`'s sampling: Q's on the camera side, W's
    /// on the light side (0 unguided).
    pub(super) fn guide_share(&self, side: Side) -> f32 {
        let guided = match side {
            Side::Camera => self.guide.is_some(),
            Side::Light => self.importance.is_some(),
        };
        if guided {
            self.settings.guide_probability
        } else {
            0.0
        }
    }

    /// W's region at a light origin (`point` on an emitter of front normal `normal`).
    pub(super) fn emission_region(&self, point: Vec3, normal: Vec3) -> Option<G::Region> {
        self.importance.and_then(|w| w.locate(point, normal))
    }
}
