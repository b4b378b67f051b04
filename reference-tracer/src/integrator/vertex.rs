//! One vertex of a camera path, in the two parts around its light sample that both path
//! loops share: [`PathTracer::arrive`] (the surface reached, its emission, what the
//! roulette and the guides say there) and [`PathTracer::scatter`] (Russian roulette or
//! splitting, the direction drawn from the BSDF, the directional guide and the focal
//! guide in one mixture, the next ray). One path at a time ([`PathTracer::radiance`])
//! traces the light sample between them; the lanes ([`PathTracer::radiance_in_lanes`])
//! trace the light samples of all their paths together after both.

use glam::Vec3;
use guiding_core::{
    DirectionalDistribution, FocalArrival, FocalGuide, Guide, Hit, Intersector, Lambertian, Pcg32, Ray, RouletteCell,
    RouletteImage, RouletteScale, StrategyArrival,
};

use super::counters::PathCounters;
use super::tracer::{
    nee_partner_pdf, Branch, NeeCells, PathScratch, PathTracer, ScalarBsdf, SurfaceInteraction, VertexStrategies,
};
use crate::color::luminance;
use crate::material::{Material, Surface};
use crate::metrics::RELATIVE_EPSILON;

/// The most copies one camera path adds by splitting: each costs a ray to re-enter its
/// vertex and a continuation, and a path of many splits would hold up its pass.
const MAX_COPIES: u32 = 16;

/// What a pass's camera paths do, the same for all of them.
#[derive(Clone, Copy, Debug)]
pub(super) struct PassRoles {
    /// The directional or focal guide learns from the paths.
    pub(super) learning: bool,
    /// Next-event estimation runs only to teach the guides (see `nee_kickstart`).
    pub(super) kickstart: bool,
    /// Next-event estimation runs (the method's own, or to learn).
    pub(super) nee: bool,
    /// The efficiency-aware roulette learns (learning passes) ...
    pub(super) roulette_learns: bool,
    /// ... or decides (the others).
    pub(super) roulette_decides: bool,
}

/// A camera path between its vertices: where it goes next and what it carries.
#[derive(Clone, Copy, Debug)]
pub(super) struct CameraPath {
    /// The ray to the next vertex.
    pub(super) ray: Ray,
    /// The next vertex's depth (scattering vertices before it).
    pub(super) depth: u32,
    /// The next vertex is the one a split copy re-enters: the path counted its emission
    /// and light sample once, whole, and decided its roulette there.
    pub(super) reentering: bool,
    /// Radiance gathered so far.
    pub(super) radiance: Vec3,
    pub(super) throughput: Vec3,
    /// The throughput with every vertex that could aim at the focal boxes counted as if
    /// its direction came from the BSDF alone: Russian roulette survives by it. The focal
    /// guide gives the paths it sends through a gap a small weight (its pdf is large);
    /// surviving by that weight would end nearly all of them at the next vertex and give
    /// the few left the weight back, undoing what aiming gained. Without focal guiding it
    /// is the throughput itself.
    pub(super) roulette_throughput: Vec3,
    /// The previous vertex: its position, the pdf of the direction it sampled, whether
    /// that direction came from a delta lobe, and its light guide cell.
    pub(super) previous: Option<(Vec3, f32, bool, NeeCells)>,
    /// What the path's pixel is expected to get (the image so far, else its first
    /// vertex's cell), for the efficiency-aware roulette.
    pub(super) pixel_estimate: Option<f32>,
    /// What the frozen roulette weighs this path's continuations by, once its pixel is known.
    pub(super) roulette_scale: Option<RouletteScale>,
    /// Copies split off so far.
    pub(super) copies_made: u32,
}

impl CameraPath {
    /// A path about to trace `ray` from the camera; `pixel_estimate` (luminance) is
    /// what its pixel is expected to be, if known.
    pub(super) fn new(ray: Ray, pixel_estimate: Option<f32>) -> Self {
        Self {
            ray,
            depth: 0,
            reentering: false,
            radiance: Vec3::ZERO,
            throughput: Vec3::ONE,
            roulette_throughput: Vec3::ONE,
            previous: None,
            pixel_estimate: pixel_estimate.filter(|p| *p > 0.0 && p.is_finite()),
            roulette_scale: None,
            copies_made: 0,
        }
    }
}

/// What the first part of a vertex found for the rest of it.
pub(super) struct VertexPlan<'a, G: Guide + 'a> {
    pub(super) surface: SurfaceInteraction,
    pub(super) delta: bool,
    /// Next-event estimation's cells here.
    pub(super) nee_cells: NeeCells,
    /// The roulette's cell side, where it has one.
    pub(super) roulette_cell: Option<RouletteCell>,
    /// The continuations the frozen roulette learned here (below 1: roulette; above:
    /// splitting), where it decides.
    pub(super) learned: Option<f32>,
    /// The focal guide, where it takes part here (sampled by its share, or learning).
    pub(super) focal: Option<&'a FocalGuide>,
    pub(super) focal_share: f32,
    /// The directional guide's share here (0 where it does not guide).
    pub(super) guide_share: f32,
    pub(super) region: Option<G::Region>,
    /// The region's distribution, located once and used for every sample and pdf.
    pub(super) distribution: Option<G::Distribution<'a>>,
}

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// What this pass's paths do (see [`PassRoles`]).
    pub(super) fn pass_roles(&self) -> PassRoles {
        let settings = &self.settings;
        PassRoles {
            learning: settings.learn && (self.guide.is_some() || self.focal.is_some()),
            kickstart: self.kickstarts(),
            nee: self.estimates_nee(),
            // The efficiency-aware roulette learns in learning passes and decides in the
            // others (deciding while it learns, on door 160×120, 2.4× the relMSE at 30 s:
            // the training passes' variance is the untrained guides', and paths ended
            // early teach the guides less).
            roulette_learns: settings.learn && self.roulette.is_some(),
            roulette_decides: !settings.learn && self.roulette.is_some(),
        }
    }

    /// The first part of the vertex `path`'s ray reached (`next`: the hit and its
    /// material; `None` where the ray left the scene): its emission (or the
    /// environment's), what the roulette learned there, the guides' shares, region and
    /// distribution, and in learning passes the guide's estimate of its integral. `None`
    /// where the path ends here (it left the scene, or this is its last vertex).
    pub(super) fn arrive(
        &self,
        path: &mut CameraPath,
        next: Option<(Hit, Material)>,
        roles: PassRoles,
        rng: &mut Pcg32,
        scratch: &mut PathScratch<G::Region, G::Records>,
        counters: &mut PathCounters,
    ) -> Option<VertexPlan<'a, G>> {
        let settings = &self.settings;
        let reentering = path.reentering;
        let depth = path.depth;
        let ray = path.ray;
        if let Some((hit, _)) = &next {
            scratch.path.reached(hit.t);
        }
        let Some((hit, material)) = next else {
            if let (false, Some(environment)) = (reentering, &self.scene.environment) {
                let emitted = environment.radiance(ray.direction);
                let light_pdf = |from, _: NeeCells| {
                    self.environment_choice * self.environment_pdf(environment, from, ray.direction)
                };
                path.radiance +=
                    path.throughput * self.emission_reached(path.previous, emitted, light_pdf, &mut scratch.path);
            }
            return None;
        };
        counters.vertices += 1;
        let surface = self.interaction(&hit, material, ray.direction);
        let SurfaceInteraction { point, geometric_normal, wo, ref material, ref shading } = surface;

        // Emission from the front face.
        if !reentering && material.is_emissive() && geometric_normal.dot(wo) > 0.0 {
            let light_pdf = |from, cells: NeeCells| self.light_pdf(&hit, from, cells.light, point, geometric_normal);
            path.radiance +=
                path.throughput * self.emission_reached(path.previous, material.emission, light_pdf, &mut scratch.path);
        }
        // The roulette's cell side: the face the path arrived at.
        let roulette_cell = self.roulette.and_then(|roulette| {
            let facing = if geometric_normal.dot(wo) >= 0.0 { geometric_normal } else { -geometric_normal };
            roulette.locate(point, facing)
        });
        if let (0, None, Some(roulette), Some(cell)) = (depth, path.pixel_estimate, self.roulette, roulette_cell) {
            path.pixel_estimate = roulette.pixel_estimate(cell, luminance(path.radiance));
        }
        // What the frozen roulette learned here, read before the guides and the shadow
        // ray (the throughput it weighs is already final): the vertex's table reads below
        // are issued together, their cache misses overlap.
        if let (true, None, Some(pixel)) = (roles.roulette_decides, path.roulette_scale, path.pixel_estimate) {
            // The pixel as relMSE weighs it: √(I² + ε); once per path.
            let pixel = (pixel * pixel + RELATIVE_EPSILON).sqrt();
            path.roulette_scale = RouletteImage { pixel, ..self.roulette_image }.scale();
        }
        let learned = match (self.roulette.filter(|_| roles.roulette_decides), roulette_cell, path.roulette_scale) {
            (Some(roulette), Some(cell), Some(scale)) if !reentering => {
                roulette.continuations(cell, luminance(path.throughput), scale)
            }
            _ => None,
        };
        let normal = shading.frame.normal;
        let delta = material.is_delta();
        // Next-event estimation's cells, which it and the MIS weight of emission found
        // from here share.
        let nee_cells = if roles.nee && !delta { self.nee_cells(point) } else { NeeCells::default() };
        // The guide's share here: fixed, or learned per region (where it learned 0 the
        // guide is not even located, except to keep learning).
        let guides_here = self.guide.is_some() && !delta && depth < settings.guide_depth;
        // The guides take over only the part of the BSDF's sampling that spreads light
        // (its diffuse lobes): a coat's highlight stays as likely as the BSDF alone makes
        // it, so guiding does not double the weight of the sharp reflections of bright
        // light it was never meant to find. Unguided paths skip it: their shares are 0
        // whatever it is.
        let guided = self.guide.is_some() || self.focal.is_some();
        let guidable = if settings.guide_diffuse_lobes && guided {
            material.guidable_share(shading, wo, settings.guide_min_alpha)
        } else {
            1.0
        };
        // The focal guide's share of the scattering here (0 where it has no boxes, and
        // left out altogether in frozen passes where no region aims at them).
        let learning = roles.learning;
        let focal = self.focal.filter(|f| !delta && if learning { !f.boxes().is_empty() } else { f.aims() });
        let focal_share =
            guidable * focal.map_or(0.0, |f| f.selection_probability(point).min(settings.focal_probability));
        // Learning measures the boxes' share from every direction, sampled by them or not.
        let focal = focal.filter(|_| focal_share > 0.0 || learning);
        let guide_share = guidable
            * match self.guide_shares {
                _ if !guides_here => 0.0,
                // Frozen, and no region gives it a share: no lookup at all.
                Some(shares) if !learning && !shares.any() => 0.0,
                Some(shares) => shares.share(point).min(settings.guide_probability),
                None => settings.guide_probability,
            };
        let clock = &mut scratch.clock;
        let region = match self.guide {
            Some(guide) if guides_here && (guide_share > 0.0 || learning) => clock.time(|| guide.locate(point, normal)),
            _ => None,
        };
        if learning && !delta && !self.carries_path {
            if let (false, Some(region), Some(guide)) = (scratch.path.is_empty(), region, self.guide) {
                let (u, u_lobe) = (rng.next_vec2(), rng.next_f32());
                let estimate = clock.time(|| match material.surface {
                    Surface::Diffuse { albedo } => {
                        guide.estimate_integral(region, wo, &Lambertian { normal, albedo: luminance(albedo) }, u)
                    }
                    _ => {
                        let bsdf = ScalarBsdf { material, shading, u_lobe };
                        guide.estimate_integral(region, wo, &bsdf, u)
                    }
                });
                scratch.path.estimate(estimate);
            }
        }
        if depth + 1 >= settings.max_depth {
            return None;
        }
        let distribution = match (self.guide, region) {
            (Some(guide), Some(region)) => Some(clock.time(|| guide.distribution(region))),
            _ => None,
        };
        Some(VertexPlan {
            surface,
            delta,
            nee_cells,
            roulette_cell,
            learned,
            focal,
            focal_share,
            guide_share,
            region,
            distribution,
        })
    }

    /// The last part of a vertex planned by [`arrive`](Self::arrive), after its light
    /// sample: Russian roulette (or splitting, whose copies wait in `scratch`), the
    /// direction drawn, the throughput and the next ray, and in learning passes the
    /// record of the direction. `false` where the path ends here.
    pub(super) fn scatter(
        &self,
        path: &mut CameraPath,
        plan: &VertexPlan<'a, G>,
        roles: PassRoles,
        rng: &mut Pcg32,
        scratch: &mut PathScratch<G::Region, G::Records>,
    ) -> bool {
        let settings = &self.settings;
        let VertexPlan { ref surface, delta, nee_cells, learned, focal, focal_share, guide_share, region, .. } = *plan;
        let SurfaceInteraction { point, geometric_normal, wo, ref material, ref shading } = *surface;
        let clock = &mut scratch.clock;
        // Russian roulette, decided before the direction is drawn: a survival that
        // depended on the direction (through its fs·cos/pdf) would make the traced
        // directions, which are all the guide learns from, follow p·survival instead of
        // the p they are recorded with. Efficiency-aware where it has learned the cell: at
        // any depth, by what going on is worth against what it costs. A copy re-entering
        // its vertex goes on: the path decided there once for all.
        let plays = !path.reentering && learned.map_or(path.depth + 1 >= settings.rr_depth, |q| q < 1.0);
        let mut survival = 1.0;
        if plays {
            survival = learned.unwrap_or_else(|| path.roulette_throughput.max_element().min(0.95));
            if survival <= 0.0 || rng.next_f32() >= survival {
                return false;
            }
            path.throughput /= survival;
            path.roulette_throughput /= survival;
        } else if let Some(q) = learned.filter(|&q| q > 1.0 && settings.splitting) {
            // Splitting: ⌊q + u⌋ copies (q on average, at most MAX_COPIES a path), each
            // carrying its share of the weight; this path is the first of them.
            let copies = ((q + rng.next_f32()) as u32).min(MAX_COPIES - path.copies_made + 1).max(1);
            if copies > 1 {
                path.throughput /= copies as f32;
                path.roulette_throughput /= copies as f32;
                for _ in 1..copies {
                    scratch.branches.push(Branch {
                        ray: path.ray,
                        throughput: path.throughput,
                        roulette_throughput: path.roulette_throughput,
                        depth: path.depth,
                    });
                }
                path.copies_made += copies - 1;
            }
        }

        // Choose the next direction: the guide with probability p_guide where a region
        // exists, the BSDF otherwise; weight by the mixture pdf.
        let (u_choice, u_lobe, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
        // `mis_pdf` is what MIS with next-event estimation weighs by: the mixture without
        // the focal term, or the BSDF's share alone (`nee_partner_pdf`); any function both
        // strategies share keeps the weights summing to one, and these spare a focal (and
        // a guide) pdf per light sample.
        let (mut focal_arrival, mut focal_pdf_pending, mut guide_arrival) = (None, false, None);
        let distribution = plan.distribution.as_ref();
        let (wi, factor, bsdf_factor, pdf, mis_pdf, sampled_delta) = if delta {
            let Some(s) = material.sample(shading, wo, u, u_lobe) else { return false };
            (s.wi, s.weight, s.weight, s.pdf, s.pdf, true)
        } else {
            let guide_probability = if distribution.is_some() { guide_share } else { 0.0 };
            // A direction drawn from a guide comes with that guide's pdf: not evaluated twice.
            let (wi, f, guide_pdf, focal_pdf) = match (distribution, focal) {
                (_, Some(focal)) if u_choice < focal_share && focal_share > 0.0 => {
                    let u_point = Vec3::new(u_choice / focal_share, u.x, u.y);
                    let Some(s) = clock.time(|| focal.sample(point, u_lobe, u_point)) else { return false };
                    (s.direction, material.eval(shading, wo, s.direction), None, Some(s.pdf))
                }
                (Some(distribution), _) if u_choice < focal_share + guide_probability => {
                    let s = clock.time(|| distribution.sample(u));
                    (s.direction, material.eval(shading, wo, s.direction), Some(s.pdf), None)
                }
                _ => {
                    let Some(s) = material.sample(shading, wo, u, u_lobe) else { return false };
                    (s.wi, s.weight * s.pdf, None, None)
                }
            };
            if f == Vec3::ZERO {
                return false;
            }
            let guide_pdf = match (distribution, guide_pdf) {
                (Some(distribution), None) => Some(clock.time(|| distribution.pdf(wi))),
                (_, known) => known,
            };
            let focal_pdf = match (focal, focal_pdf) {
                (Some(focal), None) if focal_share > 0.0 => Some(clock.time(|| focal.pdf(point, wi))),
                (_, known) => known,
            };
            focal_pdf_pending = focal.is_some() && focal_pdf.is_none();
            let focal_pdf = focal_pdf.unwrap_or(0.0);
            let bsdf_pdf = material.pdf(shading, wo, wi);
            let mixture = self.mix_pdf(bsdf_pdf, guide_pdf.map(|g| (g, guide_share)), focal_share);
            let pdf = mixture + focal_share * focal_pdf;
            let mis_pdf = if settings.nee_weighs_guide {
                mixture
            } else {
                nee_partner_pdf(bsdf_pdf, guide_probability, focal_share)
            };
            if !(pdf.is_finite() && pdf > 0.0) {
                return false;
            }
            if let (Some(_), Some(strategy_pdf)) = (self.guide_shares, guide_pdf) {
                // As for the focal arrival, the integrand waits for what arrives.
                let integrand = luminance(f);
                let selection = guide_share;
                guide_arrival = Some(StrategyArrival { point, integrand, pdf, strategy_pdf, bsdf_pdf, selection });
            }
            if focal.is_some() {
                // The integrand is filled in once the path knows what arrived.
                let integrand = luminance(f);
                let selection = focal_share;
                focal_arrival =
                    Some(FocalArrival { point, direction: wi, integrand, pdf, focal_pdf, bsdf_pdf, selection });
            }
            // Where the mixture cannot aim at the focal boxes the two factors are one:
            // unguided and directionally guided paths survive as they always did (the
            // BSDF-only rule was measured for focal guiding alone, and the GPU tracer,
            // which has no focal guide, keeps the same rule).
            let aims = focal_share > 0.0;
            let bsdf_factor = if aims && bsdf_pdf > 0.0 { f / bsdf_pdf } else { f / pdf };
            (wi, f / pdf, bsdf_factor, pdf, mis_pdf, false)
        };
        if !factor.is_finite() {
            return false;
        }
        path.throughput *= factor;
        path.roulette_throughput *= bsdf_factor;
        // The scalar factor this vertex applies to what arrives along `wi`: fs·cos/pdf
        // and, past Russian roulette, 1/survival, exactly as the throughput has it.
        let carried = luminance(factor) / survival;
        // Only directions that are actually traced are learned from. A vertex without an
        // estimate of its own (delta, or no region, or every vertex when the guide learns
        // from the path's continuation) passes its target back to the previous one,
        // scaled by its factor.
        if roles.learning {
            if delta || region.is_none() || self.carries_path {
                scratch.path.carry(carried);
            }
            let strategies = VertexStrategies {
                // Drawn only for a focal guide: other guides' paths keep their numbers.
                u_record: if self.focal.is_some() { rng.next_f32() } else { 0.5 },
                focal_arrival,
                focal_pdf_pending,
                guide_arrival,
            };
            scratch.path.scattered(region, point, wi, pdf, luminance(path.throughput), strategies);
        }
        path.ray = Ray::new(self.spawn(point, geometric_normal, wi), wi);
        path.previous = Some((point, mis_pdf, sampled_delta, nee_cells));
        path.depth += 1;
        path.reentering = false;
        true
    }
}
