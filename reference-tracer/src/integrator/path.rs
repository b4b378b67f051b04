//! One path: scattering by the BSDF, the directional guide and the focal guide in one
//! mixture, Russian roulette, and what the finished path teaches every learner.

use glam::Vec3;
use guiding_core::{
    DirectionalDistribution, FocalArrival, FocalRecord, Guide, Intersector, Lambertian, PathRecorder, Pcg32, Ray,
    RouletteImage, StrategyArrival,
};

use super::counters::{PathCounters, TIMED_PATH_STRIDE};
use super::tracer::{
    nee_partner_pdf, Branch, GuideClock, LearnedLightSample, NeeCells, PathScratch, PathTracer, RouletteVertex,
    ScalarBsdf, SurfaceInteraction, VertexStrategies,
};
use crate::color::luminance;
use crate::material::{Material, ShadingFrame, Surface};
use crate::metrics::RELATIVE_EPSILON;
use crate::sampling::power_heuristic;

/// The most copies one camera path adds by splitting: each costs a ray to re-enter its
/// vertex and a continuation, and a path of many splits would hold up its pass.
const MAX_COPIES: u32 = 16;

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// Radiance arriving along `ray` (one sample), adding its counters to `counters`.
    /// `pixel_estimate` (luminance) is what the path's pixel is expected to be, for the
    /// efficiency-aware roulette (else it estimates it from its own cells).
    pub fn radiance(
        &self,
        mut ray: Ray,
        pixel_estimate: Option<f32>,
        rng: &mut Pcg32,
        scratch: &mut PathScratch<G::Region, G::Records>,
        counters: &mut PathCounters,
    ) -> Vec3 {
        let settings = &self.settings;
        let learning = settings.learn && (self.guide.is_some() || self.focal.is_some());
        // Next-event estimation: the method's own, or only to learn from (then the guides
        // learn the full incident radiance: see `nee_kickstart`).
        let kickstart = self.kickstarts();
        let nee = self.estimates_nee();
        scratch.path.clear();
        scratch.light_samples.clear();
        scratch.roulette_vertices.clear();
        // The efficiency-aware roulette learns in learning passes and decides in the others
        // (deciding while it learns, on door 160×120, 2.4× the relMSE at 30 s: the
        // training passes' variance is the untrained guides', and paths ended early teach
        // the guides less).
        let roulette_learns = settings.learn && self.roulette.is_some();
        let roulette_decides = !settings.learn && self.roulette.is_some();
        // What the path's pixel is expected to get (the image so far, else its first
        // vertex's cell).
        let mut pixel_estimate = pixel_estimate.filter(|p| *p > 0.0 && p.is_finite());
        // What the frozen roulette weighs this path's continuations by, once its pixel is known.
        let mut roulette_scale = None;
        scratch.clock =
            GuideClock { enabled: self.guide.is_some() && counters.paths % TIMED_PATH_STRIDE == 0, nanos: 0 };
        let clock = &mut scratch.clock;
        let mut radiance = Vec3::ZERO;
        let mut throughput = Vec3::ONE;
        // The throughput with every vertex that could aim at the focal boxes counted as
        // if its direction came from the BSDF alone: Russian roulette survives by it.
        // The focal guide gives the paths it sends through a gap a small weight (its
        // pdf is large); surviving by that weight would end nearly all of them at the
        // next vertex and give the few left the weight back, undoing what aiming gained.
        // Without focal guiding it is the throughput itself.
        let mut roulette_throughput = Vec3::ONE;
        // The previous vertex: its position, the pdf of the direction it sampled, whether
        // that direction came from a delta lobe, and its light guide cell.
        let mut previous: Option<(Vec3, f32, bool, NeeCells)> = None;
        counters.paths += 1;
        // Copies of a split path waiting to be traced: each re-enters the vertex it split
        // at by that vertex's incoming ray, and goes on from there without the vertex's
        // emission and light sample (the path counted them once, whole).
        scratch.branches.clear();
        let (mut first_depth, mut reentry, mut copies_made) = (0, false, 0);
        loop {
            for depth in first_depth..settings.max_depth {
                let reentering = reentry && depth == first_depth;
                counters.rays += 1;
                let next = self.next_surface(ray, rng, counters);
                if let Some((hit, _)) = &next {
                    scratch.path.reached(hit.t);
                }
                let Some((hit, material)) = next else {
                    if let (false, Some(environment)) = (reentering, &self.scene.environment) {
                        let emitted = environment.radiance(ray.direction);
                        let light_pdf = |from, _: NeeCells| {
                            self.environment_choice * self.environment_pdf(environment, from, ray.direction)
                        };
                        radiance += throughput * self.emission_reached(previous, emitted, light_pdf, &mut scratch.path);
                    }
                    break;
                };
                counters.vertices += 1;
                let surface = self.interaction(&hit, material, ray.direction);
                let SurfaceInteraction { point, geometric_normal, wo, ref material, ref shading } = surface;

                // Emission from the front face.
                if !reentering && material.is_emissive() && geometric_normal.dot(wo) > 0.0 {
                    let light_pdf =
                        |from, cells: NeeCells| self.light_pdf(&hit, from, cells.light, point, geometric_normal);
                    radiance +=
                        throughput * self.emission_reached(previous, material.emission, light_pdf, &mut scratch.path);
                }
                // The roulette's cell side: the face the path arrived at.
                let roulette_cell = self.roulette.and_then(|roulette| {
                    let facing = if geometric_normal.dot(wo) >= 0.0 { geometric_normal } else { -geometric_normal };
                    roulette.locate(point, facing)
                });
                if let (0, None, Some(roulette), Some(cell)) = (depth, pixel_estimate, self.roulette, roulette_cell) {
                    pixel_estimate = roulette.pixel_estimate(cell, luminance(radiance));
                }
                // What the frozen roulette learned here, read before the guides and the
                // shadow ray (the throughput it weighs is already final): the vertex's
                // table reads below are issued together, their cache misses overlap.
                if let (true, None, Some(pixel)) = (roulette_decides, roulette_scale, pixel_estimate) {
                    // The pixel as relMSE weighs it: √(I² + ε); once per path.
                    let pixel = (pixel * pixel + RELATIVE_EPSILON).sqrt();
                    roulette_scale = RouletteImage { pixel, ..self.roulette_image }.scale();
                }
                let learned = match (self.roulette.filter(|_| roulette_decides), roulette_cell, roulette_scale) {
                    (Some(roulette), Some(cell), Some(scale)) if !reentering => {
                        roulette.continuations(cell, luminance(throughput), scale)
                    }
                    _ => None,
                };
                let before_light_sample = luminance(radiance);
                let normal = shading.frame.normal;
                let delta = material.is_delta();
                // Next-event estimation's cells, which it and the MIS weight of emission
                // found from here share.
                let nee_cells = if nee && !delta { self.nee_cells(point) } else { NeeCells::default() };
                // The guide's share here: fixed, or learned per region (where it learned 0 the
                // guide is not even located, except to keep learning).
                let guides_here = self.guide.is_some() && !delta && depth < settings.guide_depth;
                // The guides take over only the part of the BSDF's sampling that spreads
                // light (its diffuse lobes): a coat's highlight stays as likely as the BSDF
                // alone makes it, so guiding does not double the weight of the sharp
                // reflections of bright light it was never meant to find.
                // Unguided paths skip it: their shares are 0 whatever it is.
                let guided = self.guide.is_some() || self.focal.is_some();
                let guidable = if settings.guide_diffuse_lobes && guided {
                    material.guidable_share(shading, wo, settings.guide_min_alpha)
                } else {
                    1.0
                };
                // The focal guide's share of the scattering here (0 where it has no boxes, and
                // left out altogether in frozen passes where no region aims at them).
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
                let region = match self.guide {
                    Some(guide) if guides_here && (guide_share > 0.0 || learning) => {
                        clock.time(|| guide.locate(point, normal))
                    }
                    _ => None,
                };
                if learning && !delta && !self.carries_path {
                    if let (false, Some(region), Some(guide)) = (scratch.path.is_empty(), region, self.guide) {
                        let (u, u_lobe) = (rng.next_vec2(), rng.next_f32());
                        let estimate = clock.time(|| match material.surface {
                            Surface::Diffuse { albedo } => guide.estimate_integral(
                                region,
                                wo,
                                &Lambertian { normal, albedo: luminance(albedo) },
                                u,
                            ),
                            _ => {
                                let bsdf = ScalarBsdf { material, shading, u_lobe };
                                guide.estimate_integral(region, wo, &bsdf, u)
                            }
                        });
                        scratch.path.estimate(estimate);
                    }
                }
                if depth + 1 >= settings.max_depth {
                    break;
                }

                // The region's distribution, located once and used for every sample and pdf.
                let distribution = match (self.guide, region) {
                    (Some(guide), Some(region)) => Some(clock.time(|| guide.distribution(region))),
                    _ => None,
                };
                if nee && !delta && !reentering {
                    let direct = self.direct_light(
                        &surface,
                        nee_cells,
                        (distribution.as_ref(), guide_share, focal_share),
                        rng,
                        (clock, &mut scratch.nee_records),
                        counters,
                    );
                    radiance += throughput * direct.radiance;
                    // A guide learning the full incident radiance has this light in its own
                    // ∫ Q fs cos already: the predecessor's estimate must not count it twice.
                    if !(kickstart && scratch.path.last_is_estimated()) {
                        scratch.path.arrive(luminance(direct.radiance));
                    }
                    if let (Some(mut record), Some(region)) = (direct.sample, region) {
                        if let Some(focal) = focal.filter(|_| focal_share > 0.0) {
                            record.scatter_pdf += focal_share * clock.time(|| focal.pdf(point, record.direction));
                        }
                        scratch.light_samples.push(LearnedLightSample { region, record });
                    }
                }

                if let (true, Some(cell)) = (roulette_learns, roulette_cell) {
                    scratch.roulette_vertices.push(RouletteVertex {
                        cell,
                        throughput: luminance(throughput),
                        before_light_sample,
                        after_light_sample: luminance(radiance),
                        rays: counters.rays,
                    });
                }

                // Russian roulette, decided before the direction is drawn: a survival that
                // depended on the direction (through its fs·cos/pdf) would make the traced
                // directions, which are all the guide learns from, follow p·survival instead
                // of the p they are recorded with. Efficiency-aware where it has learned the
                // cell: at any depth, by what going on is worth against what it costs.
                // A copy re-entering its vertex goes on: the path decided there once for all.
                let plays = !reentering && learned.map_or(depth + 1 >= settings.rr_depth, |q| q < 1.0);
                let mut survival = 1.0;
                if plays {
                    survival = learned.unwrap_or_else(|| roulette_throughput.max_element().min(0.95));
                    if survival <= 0.0 || rng.next_f32() >= survival {
                        break;
                    }
                    throughput /= survival;
                    roulette_throughput /= survival;
                } else if let Some(q) = learned.filter(|&q| q > 1.0 && settings.splitting) {
                    // Splitting: ⌊q + u⌋ copies (q on average, at most MAX_COPIES a path), each
                    // carrying its share of the weight; this path is the first of them.
                    let copies = ((q + rng.next_f32()) as u32).min(MAX_COPIES - copies_made + 1).max(1);
                    if copies > 1 {
                        throughput /= copies as f32;
                        roulette_throughput /= copies as f32;
                        for _ in 1..copies {
                            scratch.branches.push(Branch { ray, throughput, roulette_throughput, depth });
                        }
                        copies_made += copies - 1;
                    }
                }

                // Choose the next direction: the guide with probability p_guide where a region
                // exists, the BSDF otherwise; weight by the mixture pdf.
                let (u_choice, u_lobe, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
                // `mis_pdf` is what MIS with next-event estimation weighs by: the mixture
                // without the focal term, or the BSDF's share alone (`nee_partner_pdf`); any
                // function both strategies share keeps the weights summing to one, and these
                // spare a focal (and a guide) pdf per light sample.
                let (mut focal_arrival, mut focal_pdf_pending, mut guide_arrival) = (None, false, None);
                let (wi, factor, bsdf_factor, pdf, mis_pdf, sampled_delta) = if delta {
                    let Some(s) = material.sample(shading, wo, u, u_lobe) else { break };
                    (s.wi, s.weight, s.weight, s.pdf, s.pdf, true)
                } else {
                    let guide_probability = if distribution.is_some() { guide_share } else { 0.0 };
                    // A direction drawn from a guide comes with that guide's pdf: not evaluated twice.
                    let (wi, f, guide_pdf, focal_pdf) = match (&distribution, focal) {
                        (_, Some(focal)) if u_choice < focal_share && focal_share > 0.0 => {
                            let u_point = Vec3::new(u_choice / focal_share, u.x, u.y);
                            let Some(s) = clock.time(|| focal.sample(point, u_lobe, u_point)) else { break };
                            (s.direction, material.eval(shading, wo, s.direction), None, Some(s.pdf))
                        }
                        (Some(distribution), _) if u_choice < focal_share + guide_probability => {
                            let s = clock.time(|| distribution.sample(u));
                            (s.direction, material.eval(shading, wo, s.direction), Some(s.pdf), None)
                        }
                        _ => {
                            let Some(s) = material.sample(shading, wo, u, u_lobe) else { break };
                            (s.wi, s.weight * s.pdf, None, None)
                        }
                    };
                    if f == Vec3::ZERO {
                        break;
                    }
                    let guide_pdf = match (&distribution, guide_pdf) {
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
                        break;
                    }
                    if let (Some(_), Some(strategy_pdf)) = (self.guide_shares, guide_pdf) {
                        // As for the focal arrival, the integrand waits for what arrives.
                        let integrand = luminance(f);
                        let selection = guide_share;
                        guide_arrival =
                            Some(StrategyArrival { point, integrand, pdf, strategy_pdf, bsdf_pdf, selection });
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
                    break;
                }
                throughput *= factor;
                roulette_throughput *= bsdf_factor;
                // The scalar factor this vertex applies to what arrives along `wi`: fs·cos/pdf
                // and, past Russian roulette, 1/survival, exactly as the throughput has it.
                let carried = luminance(factor) / survival;
                // Only directions that are actually traced are learned from. A vertex without
                // an estimate of its own (delta, or no region, or every vertex when the guide
                // learns from the path's continuation) passes its target back to the previous
                // one, scaled by its factor.
                if learning {
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
                    scratch.path.scattered(region, point, wi, pdf, luminance(throughput), strategies);
                }
                ray = Ray::new(self.spawn(point, geometric_normal, wi), wi);
                previous = Some((point, mis_pdf, sampled_delta, nee_cells));
            }
            let Some(branch) = scratch.branches.pop() else { break };
            (ray, throughput, roulette_throughput, first_depth) =
                (branch.ray, branch.throughput, branch.roulette_throughput, branch.depth);
            previous = None;
            reentry = true;
        }
        if radiance.max_element() > 0.0 {
            counters.nonzero_paths += 1;
        }
        if let (true, Some(roulette)) = (roulette_learns, self.roulette) {
            let gathered = luminance(radiance);
            for vertex in scratch.roulette_vertices.iter().filter(|v| v.throughput > 0.0) {
                let outgoing = (gathered - vertex.before_light_sample).max(0.0) / vertex.throughput;
                let continuation = (gathered - vertex.after_light_sample).max(0.0) / vertex.throughput;
                // Rays are the cost: those the path cast after deciding to go on here.
                let went_on = counters.rays - vertex.rays;
                roulette.record(vertex.cell, outgoing, continuation, (went_on > 0).then_some(went_on as f32));
            }
        }
        if learning {
            // Drawn after the path, so the share leaves the path's own numbers alone.
            let focal_learns = self.focal.is_some() && rng.next_f32() < settings.focal_learning_share;
            let (path, light_samples, records) = (&scratch.path, &scratch.light_samples, &mut scratch.records);
            scratch.clock.time(|| self.teach_learners(path, light_samples, records, focal_learns));
        }
        if scratch.clock.enabled {
            counters.timed_paths += 1;
            counters.timed_guide_nanos += scratch.clock.nanos;
        }
        radiance
    }

    /// The pdf of scattering `wi` from `wo` without the focal term: the BSDF's share
    /// (what `focal_share` and the guide leave it), plus the guide's density `guide_pdf`
    /// of `wi` where a region exists.
    pub(super) fn scatter_pdf(
        &self,
        material: &Material,
        shading: &ShadingFrame,
        wo: Vec3,
        wi: Vec3,
        guide: Option<(f32, f32)>,
        focal_share: f32,
    ) -> f32 {
        self.mix_pdf(material.pdf(shading, wo, wi), guide, focal_share)
    }

    /// [`scatter_pdf`](Self::scatter_pdf) from the BSDF's pdf; `guide` is the guide's
    /// density of the direction and its share here.
    pub(super) fn mix_pdf(&self, bsdf_pdf: f32, guide: Option<(f32, f32)>, focal_share: f32) -> f32 {
        match guide {
            Some((guide_pdf, p)) => p * guide_pdf + (1.0 - p - focal_share) * bsdf_pdf,
            None => (1.0 - focal_share) * bsdf_pdf,
        }
    }

    /// What of `emitted` (radiance) the path counts where its scattered direction from
    /// `previous` (point, mixture pdf, delta, cells) reached it: weighed by MIS against
    /// next-event estimation, whose density of the same point `light_pdf(from, cells)`
    /// gives (per steradian, before the gate), asked only where next-event estimation
    /// could have found it. Tells the recorder what arrived; under the kickstart the
    /// guide learns the emission whole, this direction weighed by the density of both
    /// strategies that find it (the light samples too).
    fn emission_reached(
        &self,
        previous: Option<(Vec3, f32, bool, NeeCells)>,
        emitted: Vec3,
        light_pdf: impl FnOnce(Vec3, NeeCells) -> f32,
        path: &mut PathRecorder<G::Region, VertexStrategies>,
    ) -> Vec3 {
        let (weight, light_pdf) = self.emission_weight(previous, light_pdf);
        path.arrive(weight * luminance(emitted));
        if self.kickstarts() {
            path.arrive_learned_only((1.0 - weight) * luminance(emitted));
            path.add_density(light_pdf);
        }
        emitted * weight
    }

    /// The MIS weight of `emitted` light reached by the direction scattered from
    /// `previous` (point, mixture pdf, delta, cells), and next-event estimation's density
    /// of the same point (`light_pdf(from, cells)`, gated), 0 where it could not have
    /// found it (then the weight is 1).
    pub(super) fn emission_weight(
        &self,
        previous: Option<(Vec3, f32, bool, NeeCells)>,
        light_pdf: impl FnOnce(Vec3, NeeCells) -> f32,
    ) -> (f32, f32) {
        match previous {
            Some((from, pdf, false, cells)) if self.estimates_nee() => {
                let light_pdf = cells.probability * light_pdf(from, cells);
                (power_heuristic(pdf, light_pdf), light_pdf)
            }
            _ => (1.0, 0.0),
        }
    }

    /// Teaches the finished path to every learner: the directional guide its Eq. (1)
    /// targets (from the recorder, through the thread's `records`), the learned shares
    /// and the focal guide what arrived along each direction. Rejected targets are
    /// counted by the guide itself (its `stats()`).
    pub(super) fn teach_learners(
        &self,
        path: &PathRecorder<G::Region, VertexStrategies>,
        light_samples: &[LearnedLightSample<G::Region>],
        records: &mut G::Records,
        focal_learns: bool,
    ) {
        let focal = self.focal.filter(|_| focal_learns);
        let weighted = self.settings.density_weighted_learning;
        // Light samples (learning passes of `nee_kickstart` only): each is one more
        // direction of incident radiance at its vertex, drawn by the deterministic mixture
        // of light sampling and scattering. The focal guide leaves them out: it would take
        // the lights themselves for gaps to aim at, from rooms that cannot see them
        // (door 160×120, 20 s, frozen passes' relMSE × spp 350 with them, 217 without).
        if let Some(guide) = self.guide {
            for sample in light_samples {
                let record = &sample.record;
                let pdf = record.light_pdf + record.scatter_pdf;
                guide.record(records, sample.region, record.direction, record.incident, pdf);
            }
        }
        // One pass over the targets feeds every learner.
        for (vertex, target) in path.targets() {
            if let Some(guide) = self.guide {
                vertex.teach_into(guide, records, target, weighted);
            }
            let strategies = &vertex.extra;
            if let (Some(shares), Some(arrival)) = (self.guide_shares, strategies.guide_arrival) {
                shares.record(&StrategyArrival { integrand: arrival.integrand * target, ..arrival });
            }
            let Some(focal) = focal else { continue };
            if let Some(arrival) = strategies.focal_arrival {
                let integrand = arrival.integrand * target;
                let focal_pdf = if strategies.focal_pdf_pending && integrand > 0.0 {
                    focal.pdf(arrival.point, vertex.direction)
                } else {
                    arrival.focal_pdf
                };
                focal.record_arrival(&FocalArrival { integrand, focal_pdf, ..arrival });
            }
            let weight = vertex.throughput * target;
            if weight > 0.0 {
                let record =
                    FocalRecord { origin: vertex.origin, direction: vertex.direction, length: vertex.length, weight };
                focal.record(&record, strategies.u_record);
            }
        }
    }
}
