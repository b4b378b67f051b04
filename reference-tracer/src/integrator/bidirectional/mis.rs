//! The strategies' weights: every vertex's density under either side's sampling, and
//! the power heuristic over all strategies that make a path (pbrt-v3's ratio recursion).

use glam::Vec3;
use guiding_core::{DirectionalDistribution, Guide, Intersector};

use super::vertex::{Side, SubpathVertex, VertexKind};
use crate::integrator::tracer::PathTracer;

/// The power heuristic's term for one strategy ratio: (p_other / p_this)² with zero
/// densities (delta lobes) counted as 1, as they cancel between strategies.
fn ratio_squared(reverse: f32, forward: f32) -> f32 {
    let remap = |p: f32| if p != 0.0 { p } else { 1.0 };
    let ratio = remap(reverse) / remap(forward);
    ratio * ratio
}

impl<I: Intersector, G: Guide> PathTracer<'_, I, G> {
    /// Density per unit area at `next` of `vertex` scattering (or emitting, or looking)
    /// towards it, having been reached from `previous` (surfaces only), by `side`'s
    /// sampling: the camera side mixes in the guide where bdpt-guided has a region.
    pub(super) fn density_towards(
        &self,
        vertex: &SubpathVertex<G::Region>,
        previous: Option<&SubpathVertex<G::Region>>,
        next: &SubpathVertex<G::Region>,
        side: Side,
    ) -> f32 {
        self.density_towards_with(vertex, previous, next, side, None)
    }

    /// [`density_towards`](Self::density_towards) of `vertex` back towards
    /// `predecessor`, the vertex before it on its own subpath, by the other side's
    /// sampling (`side`): the guide's part is the one the walk cached at `vertex`.
    pub(super) fn density_back(
        &self,
        vertex: &SubpathVertex<G::Region>,
        previous: Option<&SubpathVertex<G::Region>>,
        predecessor: &SubpathVertex<G::Region>,
        side: Side,
    ) -> f32 {
        self.density_towards_with(vertex, previous, predecessor, side, vertex.back_guide_pdf)
    }

    /// The guide's density per steradian at surface `vertex` towards `next` under
    /// `side`'s sampling, where that side guides there: the part of
    /// [`density_towards`](Self::density_towards) a walk can compute once per vertex.
    pub(super) fn guide_density_towards(
        &self,
        vertex: &SubpathVertex<G::Region>,
        next: &SubpathVertex<G::Region>,
        side: Side,
    ) -> Option<f32> {
        let offset = next.point - vertex.point;
        let distance = offset.length();
        if vertex.kind != VertexKind::Surface || !distance.is_finite() || distance <= 0.0 {
            return None;
        }
        let (guide, region) = match side {
            Side::Camera => (self.guide, vertex.region),
            Side::Light => (self.importance, vertex.importance_region),
        };
        match (guide, region) {
            (Some(guide), Some(region)) if self.guide_share(side) > 0.0 => {
                Some(guide.distribution(region).pdf(offset / distance))
            }
            _ => None,
        }
    }

    /// [`density_towards`](Self::density_towards) with the guide's density towards
    /// `next` given (`guide_pdf`, from [`guide_density_towards`]) or found by it here.
    ///
    /// [`guide_density_towards`]: Self::guide_density_towards
    fn density_towards_with(
        &self,
        vertex: &SubpathVertex<G::Region>,
        previous: Option<&SubpathVertex<G::Region>>,
        next: &SubpathVertex<G::Region>,
        side: Side,
        guide_pdf: Option<f32>,
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
                    match guide_pdf.or_else(|| self.guide_density_towards(vertex, next, side)) {
                        Some(guided) => {
                            let p_guide = self.guide_share(side);
                            p_guide * guided + (1.0 - p_guide) * bsdf
                        }
                        None => bsdf,
                    }
                }
                _ => 0.0,
            },
        };
        vertex.area_density(pdf_dir, next)
    }

    /// Density per steradian of a light subpath leaving emitter point `vertex` along
    /// `wi`: the cosine about its front normal, mixed in bdpt-guided with W there.
    pub(super) fn emission_direction_pdf(&self, vertex: &SubpathVertex<G::Region>, wi: Vec3) -> f32 {
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
    pub(super) fn light_origin_pdf(&self, vertex: &SubpathVertex<G::Region>) -> f32 {
        let lights = &self.scene.lights;
        vertex.light.map_or(0.0, |light| lights.power_probability(light) / lights.light(light).2)
    }

    /// Strategy (s, t)'s power-heuristic weight among all strategies that make the same
    /// path: 1 / Σ_k (p_k / p_(s,t))², the density ratios built up vertex by vertex
    /// outwards from the connection; `sampled` is the light vertex s = 1 drew.
    pub(super) fn mis_weight(
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
            Some(qs) => self.density_back(pt, Some(qs), pm, Side::Light),
            None => {
                let offset = pm.point - pt.point;
                pt.area_density(self.emission_direction_pdf(pt, offset.normalize_or_zero()), pm)
            }
        });
        let qs_reverse = qs.map_or(0.0, |qs| self.density_towards(pt, pt_minus, qs, Side::Camera));
        let qs_minus_reverse = match (qs, qs_minus) {
            (Some(qs), Some(qm)) => self.density_back(qs, Some(pt), qm, Side::Camera),
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

    use glam::Vec3;
    use guiding_core::{HemisphereGrid, Pcg32};

    use super::super::BidirectionalScratch;
    use super::*;
    use crate::integrator::counters::PathCounters;
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
            // The camera walk cached W's density towards its own predecessor; a light
            // walk caches Q's towards the vertex before it on the light side.
            light[j].back_guide_pdf = tracer.guide_density_towards(&light[j], &light[j - 1], Side::Camera);
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
            let tracer: PathTracer<'_, _, HemisphereGrid> = PathTracer::new(&scene, &intersector, settings);
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
                let tracer = PathTracer::new(&scene, &intersector, settings)
                    .with_guide(Some(&grid))
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
            let tracer = PathTracer::new(&scene, &intersector, frozen)
                .with_guide(Some(&grid))
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
