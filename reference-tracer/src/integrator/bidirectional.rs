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

use glam::Vec3;
use guiding_core::{DirectionalDistribution, Frame, Guide, Intersector, PathRecorder, Pcg32, Ray};

use super::counters::PathCounters;
use super::light_path::{cosine_direction, importance_weight, shading_correction};
use super::tracer::PathTracer;
use crate::camera::EyeConnection;
use crate::color::luminance;
use crate::material::{Material, ShadingFrame};

/// What a subpath vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum VertexKind {
    /// The pinhole.
    Camera,
    /// A point on an area light, where a light subpath starts.
    Light,
    /// A surface a subpath reached.
    Surface,
}

/// One vertex of a camera or light subpath; `R` is the directional guide's region type.
#[derive(Clone, Copy, Debug)]
pub struct SubpathVertex<R> {
    kind: VertexKind,
    point: Vec3,
    /// The geometric normal (a light's emitting side; unused at the camera).
    normal: Vec3,
    /// Unit direction to the previous vertex of its own subpath (surfaces).
    wo: Vec3,
    /// A surface's material and shading frame (seen from `wo`).
    surface: Option<(Material, ShadingFrame)>,
    /// The light it lies on (light vertices, and emitters a camera subpath reached).
    light: Option<u32>,
    /// The subpath's throughput up to this vertex: radiance weight from the camera,
    /// power weight from the light (emitted radiance over the densities so far).
    beta: Vec3,
    /// Density per unit area (at this vertex) with which its own subpath reached it.
    pdf_fwd: f32,
    /// Density per unit area with which the other subpath's sampling would reach it
    /// from the next vertex of its own subpath.
    pdf_rev: f32,
    /// Whether the direction sampled here came from a delta lobe.
    delta: bool,
    /// bdpt-guided: Q's region here (surfaces whose lobes are not all delta), which the
    /// camera side's sampling mixes in.
    region: Option<R>,
    /// bdpt-guided: W's region here (the same surfaces, and light origins), which the
    /// light side's sampling mixes in.
    importance_region: Option<R>,
    /// Density per steradian of the direction sampled here (what the guide learns with).
    scatter_pdf: f32,
}

impl<R: Copy> SubpathVertex<R> {
    fn new(kind: VertexKind, point: Vec3, normal: Vec3, beta: Vec3, pdf_fwd: f32) -> Self {
        Self {
            kind,
            point,
            normal,
            wo: Vec3::ZERO,
            surface: None,
            light: None,
            beta,
            pdf_fwd,
            pdf_rev: 0.0,
            delta: false,
            region: None,
            importance_region: None,
            scatter_pdf: 0.0,
        }
    }

    /// Whether a connection may end here (a surface whose lobes are not all delta, or
    /// the camera, or a light).
    fn connectible(&self) -> bool {
        match self.kind {
            VertexKind::Surface => self.surface.is_some_and(|(material, _)| !material.is_delta()),
            VertexKind::Camera | VertexKind::Light => true,
        }
    }

    /// A density per steradian of leaving this vertex towards `next`, as a density per
    /// unit area at `next` (the cosine there, except at the camera, which is no surface).
    fn area_density(&self, pdf_dir: f32, next: &SubpathVertex<R>) -> f32 {
        let offset = next.point - self.point;
        let distance2 = offset.length_squared();
        if !distance2.is_finite() || distance2 <= 0.0 {
            return 0.0;
        }
        let mut pdf = pdf_dir / distance2;
        if next.kind != VertexKind::Camera {
            pdf *= (next.normal.dot(offset) / distance2.sqrt()).abs();
        }
        pdf
    }

    /// The radiance a camera subpath's emitter sends back along `wo` (zero elsewhere).
    fn emitted(&self) -> Vec3 {
        match self.surface {
            Some((material, _)) if self.normal.dot(self.wo) > 0.0 => material.emission,
            _ => Vec3::ZERO,
        }
    }
}

/// What is left to test of a connection: nothing (a camera subpath that reached an
/// emitter), the segment from a surface point to the eye, or one between two points.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Shadow {
    Unblocked,
    Eye { point: Vec3, normal: Vec3, eye: EyeConnection },
    Segment { from: Vec3, normal: Vec3, to: Vec3 },
}

/// A strategy's contribution before its shadow ray.
struct Connection<R> {
    /// Unweighted, as if nothing blocked it.
    value: Vec3,
    /// The light vertex s = 1 drew.
    sampled: Option<SubpathVertex<R>>,
    /// The pixel a t = 1 connection lands in.
    pixel: Option<(u32, u32)>,
    shadow: Shadow,
}

impl<R> Connection<R> {
    fn unblocked(value: Vec3) -> Self {
        Self { value, sampled: None, pixel: None, shadow: Shadow::Unblocked }
    }
}

impl Side {
    fn other(self) -> Side {
        match self {
            Side::Camera => Side::Light,
            Side::Light => Side::Camera,
        }
    }
}

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

/// Which subpath's sampling a density is of: the camera's (guided in bdpt-guided) or
/// the light's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    Camera,
    Light,
}

/// The power heuristic's term for one strategy ratio: (p_other / p_this)² with zero
/// densities (delta lobes) counted as 1, as they cancel between strategies.
fn ratio_squared(reverse: f32, forward: f32) -> f32 {
    let remap = |p: f32| if p != 0.0 { p } else { 1.0 };
    let ratio = remap(reverse) / remap(forward);
    ratio * ratio
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
                let Some(connection) = self.connect(camera, light, s, t, rng) else { continue };
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

    /// Teaches W what the light subpath found (bdpt-guided, learning passes): Eq. (1)
    /// with the roles swapped, as `light-guided` learns it. Each vertex's target is the
    /// importance the next vertex's camera connection reflects back, plus the next
    /// vertex's own target carried back by its scattering factor.
    fn teach_light_subpath(
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
                if j + 1 < light.len() {
                    let ratio = luminance(light[j + 1].beta) / luminance(vertex.beta).max(f32::MIN_POSITIVE);
                    recorder.carry(ratio);
                }
            }
            if j + 1 < light.len() {
                let next = &light[j + 1];
                let offset = next.point - vertex.point;
                let distance = offset.length();
                let region = vertex.importance_region.filter(|_| !vertex.delta);
                recorder.scattered(
                    region,
                    vertex.point,
                    offset / distance,
                    vertex.scatter_pdf,
                    luminance(next.beta),
                    (),
                );
                recorder.reached(distance);
            }
        }
        recorder.learn(importance, self.settings.density_weighted_learning);
    }

    /// The light sample of camera vertex t − 1 (its contribution `value`, unweighted,
    /// from the light point `sampled`) as the radiance it reflects towards the previous
    /// vertex, weighted by the power heuristic against the camera side's sampling finding
    /// the same light (luminance): with that weight on the emission scattering finds, the
    /// two add up to the light arriving there, as path tracing with next-event
    /// estimation estimates it.
    fn learned_direct_light(
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
    fn teach_camera_subpath(
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
                if k + 1 < camera.len() {
                    let ratio = luminance(camera[k + 1].beta) / luminance(vertex.beta).max(f32::MIN_POSITIVE);
                    recorder.carry(ratio);
                }
            }
            if k + 1 < camera.len() {
                let next = &camera[k + 1];
                let offset = next.point - vertex.point;
                let distance = offset.length();
                let region = vertex.region.filter(|_| !vertex.delta);
                recorder.scattered(
                    region,
                    vertex.point,
                    offset / distance,
                    vertex.scatter_pdf,
                    luminance(next.beta),
                    (),
                );
                recorder.reached(distance);
            }
        }
        recorder.learn(guide, self.settings.density_weighted_learning);
    }

    /// The camera subpath through pixel (`x`, `y`): the eye, then up to `max_depth`
    /// surfaces.
    fn camera_subpath(
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
    fn light_subpath(&self, rng: &mut Pcg32, path: &mut Vec<SubpathVertex<G::Region>>, counters: &mut PathCounters) {
        path.clear();
        let lights = &self.scene.lights;
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
    fn random_walk(
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
            if surface.material.is_emissive() {
                vertex.light = self.scene.lights.light_at(hit.primitive, hit.barycentrics);
            }
            // Both sides locate in both guides: a vertex's density for the other side's
            // sampling needs that side's region.
            if !surface.material.is_delta() {
                let normal = surface.shading.frame.normal;
                vertex.region = self.guide.and_then(|guide| guide.locate(surface.point, normal));
                vertex.importance_region = self.importance.and_then(|w| w.locate(surface.point, normal));
            }
            let k = path.len();
            let previous = path[k - 1];
            if !previous.delta {
                let before = k.checked_sub(2).map(|i| path[i]);
                vertex.pdf_fwd = self.density_towards(&previous, before.as_ref(), &vertex, side);
                if let Some(before) = before {
                    path[k - 2].pdf_rev = self.density_towards(&previous, Some(&vertex), &before, side.other());
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
            let (wi, factor, pdf) = match &distribution {
                Some(d) => {
                    let wi = if u_choice < p_guide {
                        d.sample(u).direction
                    } else {
                        let Some(sample) = material.sample(shading, wo, u, u_lobe) else { break };
                        sample.wi
                    };
                    let pdf = p_guide * d.pdf(wi) + (1.0 - p_guide) * material.pdf(shading, wo, wi);
                    let f = match side {
                        Side::Camera => material.eval(shading, wo, wi),
                        Side::Light => material.eval(shading, wo, wi) * shading_correction(shading, wo, wi),
                    };
                    (wi, f / pdf, pdf)
                }
                None => {
                    let Some(sample) = material.sample(shading, wo, u, u_lobe) else { break };
                    let factor = match side {
                        Side::Light => importance_weight(material, shading, wo, sample.wi, sample.weight),
                        Side::Camera => sample.weight,
                    };
                    (sample.wi, factor, sample.pdf)
                }
            };
            if !(factor.is_finite() && factor.max_element() > 0.0 && pdf > 0.0) {
                break;
            }
            beta *= factor;
            relative *= factor;
            path[k].delta = material.is_delta();
            path[k].scatter_pdf = pdf;
            ray = Ray::new(self.spawn(surface.point, surface.geometric_normal, wi), wi);
        }
    }

    /// bdpt-guided's share of the guide in `side`'s sampling: Q's on the camera side, W's
    /// on the light side (0 unguided).
    fn guide_share(&self, side: Side) -> f32 {
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
    fn emission_region(&self, point: Vec3, normal: Vec3) -> Option<G::Region> {
        self.importance.and_then(|w| w.locate(point, normal))
    }

    /// Strategy (s, t) before its shadow ray: the unweighted contribution if nothing
    /// blocks it, the light vertex it drew (s = 1), the pixel it lands in when that is
    /// not the sample's own (t = 1), and the segment left to test.
    fn connect(
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
            let (material, shading) = qs.surface.filter(|_| qs.connectible())?;
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
        let (camera_material, camera_shading) = pt.surface.filter(|_| pt.connectible())?;
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
            sampled.importance_region = self.emission_region(point, normal);
            let shadow = Shadow::Segment { from: pt.point, normal: pt.normal, to: point };
            return Some(Connection { value, sampled: Some(sampled), pixel: None, shadow });
        }
        // Two surfaces joined by a shadow ray.
        let qs = &light[s - 1];
        let (light_material, light_shading) = qs.surface.filter(|_| qs.connectible())?;
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
    fn shadow_transmittance(&self, shadow: &Shadow, counters: &mut PathCounters) -> f32 {
        match shadow {
            Shadow::Unblocked => 1.0,
            Shadow::Eye { point, normal, eye } => self.eye_transmittance(*point, *normal, eye, counters),
            Shadow::Segment { from, normal, to } => self.segment_transmittance(*from, *normal, *to, counters),
        }
    }

    /// The share of light passing between `from` (on a surface of normal `normal`) and
    /// `to` (masks weighed; 0 when blocked), stopping short of both ends by the spawn
    /// offset.
    fn segment_transmittance(&self, from: Vec3, normal: Vec3, to: Vec3, counters: &mut PathCounters) -> f32 {
        let offset = to - from;
        let distance = offset.length();
        let wi = offset / distance;
        let origin = self.spawn(from, normal, wi);
        let margin = self.epsilon_at(from) + self.epsilon_at(to);
        let t_max = (distance - margin).max(0.0) * (1.0 - 1e-5);
        counters.rays += 1;
        self.transmittance(Ray::segment(origin, wi, 0.0, t_max), counters)
    }

    /// Density per unit area at `next` of `vertex` scattering (or emitting, or looking)
    /// towards it, having been reached from `previous` (surfaces only), by `side`'s
    /// sampling: the camera side mixes in the guide where bdpt-guided has a region.
    fn density_towards(
        &self,
        vertex: &SubpathVertex<G::Region>,
        previous: Option<&SubpathVertex<G::Region>>,
        next: &SubpathVertex<G::Region>,
        side: Side,
    ) -> f32 {
        let offset = next.point - vertex.point;
        let distance = offset.length();
        if !distance.is_finite() || distance <= 0.0 {
            return 0.0;
        }
        let wi = offset / distance;
        let pdf_dir = match vertex.kind {
            VertexKind::Camera => self.scene.camera.direction_pdf(wi),
            VertexKind::Light => self.emission_direction_pdf(vertex, wi),
            VertexKind::Surface => match (vertex.surface, previous) {
                (Some((material, shading)), Some(previous)) => {
                    let wo = (previous.point - vertex.point).normalize_or_zero();
                    let bsdf = material.pdf(&shading, wo, wi);
                    let p_guide = self.guide_share(side);
                    let (guide, region) = match side {
                        Side::Camera => (self.guide, vertex.region),
                        Side::Light => (self.importance, vertex.importance_region),
                    };
                    match (guide, region) {
                        (Some(guide), Some(region)) if p_guide > 0.0 => {
                            p_guide * guide.distribution(region).pdf(wi) + (1.0 - p_guide) * bsdf
                        }
                        _ => bsdf,
                    }
                }
                _ => 0.0,
            },
        };
        vertex.area_density(pdf_dir, next)
    }

    /// Density per steradian of a light subpath leaving emitter point `vertex` along
    /// `wi`: the cosine about its front normal, mixed in bdpt-guided with W there.
    fn emission_direction_pdf(&self, vertex: &SubpathVertex<G::Region>, wi: Vec3) -> f32 {
        let cosine = vertex.normal.dot(wi).max(0.0) * std::f32::consts::FRAC_1_PI;
        let p_guide = self.guide_share(Side::Light);
        if p_guide <= 0.0 {
            return cosine;
        }
        // Located as the light subpath locates it (a camera vertex on an emitter has
        // none of its own as a light origin).
        let region = match vertex.kind {
            VertexKind::Light => vertex.importance_region,
            _ => self.emission_region(vertex.point, vertex.normal),
        };
        match (self.importance, region) {
            (Some(w), Some(region)) => p_guide * w.distribution(region).pdf(wi) + (1.0 - p_guide) * cosine,
            _ => cosine,
        }
    }

    /// Density per unit area with which a light subpath starts at emitter `vertex`.
    fn light_origin_pdf(&self, vertex: &SubpathVertex<G::Region>) -> f32 {
        let lights = &self.scene.lights;
        vertex.light.map_or(0.0, |light| lights.power_probability(light) / lights.light(light).2)
    }

    /// Strategy (s, t)'s power-heuristic weight among all strategies that make the same
    /// path: 1 / Σ_k (p_k / p_(s,t))², the density ratios built up vertex by vertex
    /// outwards from the connection; `sampled` is the light vertex s = 1 drew.
    fn mis_weight(
        &self,
        camera: &[SubpathVertex<G::Region>],
        light: &[SubpathVertex<G::Region>],
        sampled: Option<&SubpathVertex<G::Region>>,
        s: usize,
        t: usize,
    ) -> f32 {
        if s + t == 2 {
            return 1.0;
        }
        let qs = if s == 1 { sampled } else { s.checked_sub(1).map(|i| &light[i]) };
        let pt = &camera[t - 1];
        let pt_minus = t.checked_sub(2).map(|i| &camera[i]);
        let qs_minus = s.checked_sub(2).map(|i| &light[i]);
        // The reverse densities the connection gives the vertices on both sides of it
        // (the stored ones are for each subpath's own continuation).
        let pt_reverse = match qs {
            Some(qs) => self.density_towards(qs, qs_minus, pt, Side::Light),
            None => self.light_origin_pdf(pt),
        };
        let pt_minus_reverse = pt_minus.map_or(0.0, |pm| match qs {
            Some(qs) => self.density_towards(pt, Some(qs), pm, Side::Light),
            None => {
                let offset = pm.point - pt.point;
                pt.area_density(self.emission_direction_pdf(pt, offset.normalize_or_zero()), pm)
            }
        });
        let qs_reverse = qs.map_or(0.0, |qs| self.density_towards(pt, pt_minus, qs, Side::Camera));
        let qs_minus_reverse = match (qs, qs_minus) {
            (Some(qs), Some(qm)) => self.density_towards(qs, Some(pt), qm, Side::Camera),
            _ => 0.0,
        };
        let mut sum = 0.0f32;
        let mut ratio = 1.0f32;
        for i in (1..t).rev() {
            let reverse = if i == t - 1 {
                pt_reverse
            } else if i + 2 == t {
                pt_minus_reverse
            } else {
                camera[i].pdf_rev
            };
            ratio *= ratio_squared(reverse, camera[i].pdf_fwd);
            let delta_here = i != t - 1 && camera[i].delta;
            if !delta_here && !camera[i - 1].delta {
                sum += ratio;
            }
        }
        ratio = 1.0;
        for i in (0..s).rev() {
            let vertex = if s == 1 { qs.copied().unwrap_or(light[0]) } else { light[i] };
            let reverse = if i == s - 1 {
                qs_reverse
            } else if i + 2 == s {
                qs_minus_reverse
            } else {
                light[i].pdf_rev
            };
            ratio *= ratio_squared(reverse, vertex.pdf_fwd);
            let delta_here = i != s - 1 && light[i].delta;
            let delta_before = i > 0 && light[i - 1].delta;
            if !delta_here && !delta_before {
                sum += ratio;
            }
        }
        1.0 / (1.0 + sum)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use guiding_core::HemisphereGrid;

    use super::*;
    use crate::integrator::{IntegratorSettings, Method};
    use crate::scene::Scene;
    use crate::scene_intersector::{IntersectorChoice, SceneIntersector};

    fn repository_scene(name: &str) -> Scene {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../scenes/{name}/scene.json"));
        let scene = Scene::from_json(&path, &std::fs::read_to_string(&path).unwrap()).unwrap();
        Scene { camera: scene.camera.with_resolution(16, 16), ..scene }
    }

    /// The light-side view of camera vertices `path[from..]` traversed backwards: the
    /// emitter at the end becomes the light subpath's origin, and every density is what
    /// a light subpath's sampling (forward) and a camera subpath's (reverse) give it.
    fn reversed<I: Intersector, G: Guide>(
        tracer: &PathTracer<'_, I, G>,
        path: &[SubpathVertex<G::Region>],
        from: usize,
    ) -> Vec<SubpathVertex<G::Region>> {
        let mut light: Vec<SubpathVertex<G::Region>> = path[from..].iter().rev().copied().collect();
        light[0].kind = VertexKind::Light;
        light[0].pdf_fwd = tracer.light_origin_pdf(&light[0]);
        for j in 1..light.len() {
            light[j].wo = (light[j - 1].point - light[j].point).normalize();
        }
        for j in 1..light.len() {
            let previous = (j >= 2).then(|| light[j - 2]);
            light[j].pdf_fwd = tracer.density_towards(&light[j - 1], previous.as_ref(), &light[j], Side::Light);
        }
        // Reverse densities come from the camera side: the vertex after j, reached from
        // the one after that (the last two the connection gives their own).
        for j in 0..light.len().saturating_sub(2) {
            let (next, after) = (light[j + 1], light[j + 2]);
            light[j].pdf_rev = tracer.density_towards(&next, Some(&after), &light[j], Side::Camera);
        }
        light
    }

    /// Over random camera subpaths that reach the light, every way of cutting the path
    /// into a light and a camera part (s + t = its vertex count) that joins two
    /// vertices a connection can end at gets a weight, and the weights sum to one: the
    /// estimator counts each path exactly once. Cornell (diffuse) and glossy (mirrors,
    /// glass and rough metal).
    #[test]
    fn mis_weights_of_every_path_sum_to_one() {
        for name in ["cornell", "glossy"] {
            let scene = repository_scene(name);
            let intersector = SceneIntersector::build(&scene.triangles, IntersectorChoice::default()).unwrap();
            let settings =
                IntegratorSettings { method: Method::Bdpt, max_depth: 8, rr_depth: 64, ..Default::default() };
            let tracer: PathTracer<'_, _, HemisphereGrid> =
                PathTracer::new(&scene, &intersector, None, None, None, None, settings);
            weights_sum_to_one(&tracer, name);
        }
    }

    /// The same with camera subpaths guided by Q and light subpaths by W, two hemisphere
    /// grids that learned from bdpt-guided's own samples: the guided densities of both
    /// sides enter every weight.
    #[test]
    fn guided_mis_weights_of_every_path_sum_to_one() {
        for name in ["cornell", "glossy"] {
            let scene = repository_scene(name);
            let intersector = SceneIntersector::build(&scene.triangles, IntersectorChoice::default()).unwrap();
            let grid_settings = guiding_core::HemisphereGridSettings { probe_count: Some(40), ..Default::default() };
            let mut grid = HemisphereGrid::build(&scene.triangles, grid_settings).unwrap();
            let mut importance = HemisphereGrid::build(&scene.triangles, grid_settings).unwrap();
            let settings = IntegratorSettings {
                method: Method::BdptGuided,
                max_depth: 8,
                rr_depth: 64,
                guide_probability: 0.5,
                ..Default::default()
            };
            // Learn for a few passes, so the guide is far from uniform.
            for pass in 0..4u64 {
                let tracer = PathTracer::new(&scene, &intersector, Some(&grid), None, None, None, settings)
                    .with_importance_guide(Some(&importance));
                let mut scratch = BidirectionalScratch::default();
                let mut image = vec![Vec3::ZERO; 256];
                let mut counters = PathCounters::default();
                for pixel in 0..256u64 {
                    let mut rng = Pcg32::new(pass * 1000 + pixel, 3);
                    let xy = ((pixel % 16) as u32, (pixel / 16) as u32);
                    tracer.bidirectional_sample(xy, &mut rng, &mut image, &mut scratch, &mut counters);
                }
                grid.rebuild_sampling();
                importance.rebuild_sampling();
            }
            for (label, learned) in [("Q", &grid), ("W", &importance)] {
                let updates = learned.stats().accepted_updates;
                assert!(updates > 1000, "{name}: {label} learned {updates} updates");
            }
            let frozen = IntegratorSettings { learn: false, ..settings };
            let tracer = PathTracer::new(&scene, &intersector, Some(&grid), None, None, None, frozen)
                .with_importance_guide(Some(&importance));
            weights_sum_to_one(&tracer, &format!("{name}, guided"));
        }
    }

    fn weights_sum_to_one<I: Intersector, G: Guide>(tracer: &PathTracer<'_, I, G>, name: &str) {
        let mut counters = PathCounters::default();
        let mut camera = Vec::new();
        let (mut checked, mut through_delta) = (0, 0);
        for seed in 0..40_000u64 {
            let mut rng = Pcg32::new(seed, 7);
            tracer.camera_subpath((seed % 16) as u32, (seed / 16 % 16) as u32, &mut rng, &mut camera, &mut counters);
            // The first emitter the camera subpath reached, seen from its front.
            let Some(end) = camera.iter().position(|v| v.emitted().max_element() > 0.0) else { continue };
            if end < 2 {
                continue;
            }
            let vertices = end + 1;
            let mut sum = 0.0f64;
            for s in 0..vertices {
                let t = vertices - s;
                // A connection cannot end at a delta vertex.
                let joins_delta = camera[t - 1].delta || (s > 0 && camera[t].delta);
                if s == 1 && t == 1 || joins_delta {
                    continue;
                }
                let mut light = if s == 0 { Vec::new() } else { reversed(tracer, &camera[..vertices], t) };
                let sampled = (s == 1).then(|| light[0]);
                // The reverse densities next to the connection belong to each subpath's
                // own continuation, which a real light subpath does not share: the
                // weight must compute them, never read them.
                let mut camera_part = camera[..t].to_vec();
                for vertex in camera_part.iter_mut().rev().take(2).chain(light.iter_mut().rev().take(2)) {
                    vertex.pdf_rev = f32::NAN;
                }
                sum += tracer.mis_weight(&camera_part, &light, sampled.as_ref(), s, t) as f64;
            }
            assert!((sum - 1.0).abs() < 1e-4, "{name}, seed {seed}: {vertices} vertices, weights sum to {sum}");
            checked += 1;
            through_delta += camera[..end].iter().any(|v| v.delta) as u32;
        }
        assert!(checked > 200, "{name}: only {checked} paths reached the light");
        if name.starts_with("glossy") {
            assert!(through_delta > 20, "{name}: only {through_delta} paths met a mirror or glass");
        }
    }
}
