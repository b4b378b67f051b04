//! One camera path at a time: its vertices ([`super::vertex`]) with each light sample
//! traced between their two parts, splitting's copies, and what the finished path
//! teaches every learner.

use glam::Vec3;
use guiding_core::{FocalArrival, FocalRecord, Guide, Intersector, PathRecorder, Pcg32, Ray, StrategyArrival};

use super::counters::{PathCounters, TIMED_PATH_STRIDE};
use super::tracer::{
    GuideClock, LearnedLightSample, NeeCells, PathScratch, PathTracer, RouletteVertex, VertexStrategies,
};
use super::vertex::CameraPath;
use crate::color::luminance;
use crate::material::{Material, ShadingFrame};
use crate::sampling::power_heuristic;

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// Radiance arriving along `ray` (one sample), adding its counters to `counters`.
    /// `pixel_estimate` (luminance) is what the path's pixel is expected to be, for the
    /// efficiency-aware roulette (else it estimates it from its own cells).
    pub fn radiance(
        &self,
        ray: Ray,
        pixel_estimate: Option<f32>,
        rng: &mut Pcg32,
        scratch: &mut PathScratch<G::Region, G::Records>,
        counters: &mut PathCounters,
    ) -> Vec3 {
        let roles = self.pass_roles();
        scratch.path.clear();
        scratch.light_samples.clear();
        scratch.roulette_vertices.clear();
        scratch.clock =
            GuideClock { enabled: self.guide.is_some() && counters.paths % TIMED_PATH_STRIDE == 0, nanos: 0 };
        counters.paths += 1;
        // Copies of a split path waiting to be traced: each re-enters the vertex it split
        // at by that vertex's incoming ray, and goes on from there without the vertex's
        // emission and light sample (the path counted them once, whole).
        scratch.branches.clear();
        let mut path = CameraPath::new(ray, pixel_estimate);
        loop {
            while path.depth < self.settings.max_depth {
                counters.rays += 1;
                let next = self.next_surface(path.ray, rng, counters);
                let Some(plan) = self.arrive(&mut path, next, roles, rng, scratch, counters) else { break };
                let before_light_sample = luminance(path.radiance);
                if roles.nee && !plan.delta && !path.reentering {
                    let mixture = (plan.distribution.as_ref(), plan.guide_share, plan.focal_share);
                    let (clock, nee_records) = (&mut scratch.clock, &mut scratch.nee_records);
                    let direct =
                        self.direct_light(&plan.surface, plan.nee_cells, mixture, rng, (clock, nee_records), counters);
                    path.radiance += path.throughput * direct.radiance;
                    // A guide learning the full incident radiance has this light in its own
                    // ∫ Q fs cos already: the predecessor's estimate must not count it twice.
                    if !(roles.kickstart && scratch.path.last_is_estimated()) {
                        scratch.path.arrive(luminance(direct.radiance));
                    }
                    if let (Some(mut record), Some(region)) = (direct.sample, plan.region) {
                        if let Some(focal) = plan.focal.filter(|_| plan.focal_share > 0.0) {
                            let point = plan.surface.point;
                            record.scatter_pdf +=
                                plan.focal_share * scratch.clock.time(|| focal.pdf(point, record.direction));
                        }
                        scratch.light_samples.push(LearnedLightSample { region, record });
                    }
                }
                if let (true, Some(cell)) = (roles.roulette_learns, plan.roulette_cell) {
                    scratch.roulette_vertices.push(RouletteVertex {
                        cell,
                        throughput: luminance(path.throughput),
                        before_light_sample,
                        after_light_sample: luminance(path.radiance),
                        rays: counters.rays,
                    });
                }
                if !self.scatter(&mut path, &plan, roles, rng, scratch) {
                    break;
                }
            }
            let Some(branch) = scratch.branches.pop() else { break };
            path = CameraPath {
                ray: branch.ray,
                depth: branch.depth,
                reentering: true,
                throughput: branch.throughput,
                roulette_throughput: branch.roulette_throughput,
                previous: None,
                ..path
            };
        }
        let radiance = path.radiance;
        if radiance.max_element() > 0.0 {
            counters.nonzero_paths += 1;
        }
        if let (true, Some(roulette)) = (roles.roulette_learns, self.roulette) {
            let gathered = luminance(radiance);
            for vertex in scratch.roulette_vertices.iter().filter(|v| v.throughput > 0.0) {
                let outgoing = (gathered - vertex.before_light_sample).max(0.0) / vertex.throughput;
                let continuation = (gathered - vertex.after_light_sample).max(0.0) / vertex.throughput;
                // Rays are the cost: those the path cast after deciding to go on here.
                let went_on = counters.rays - vertex.rays;
                roulette.record(vertex.cell, outgoing, continuation, (went_on > 0).then_some(went_on as f32));
            }
        }
        if roles.learning {
            // Drawn after the path, so the share leaves the path's own numbers alone.
            let focal_learns = self.focal.is_some() && rng.next_f32() < self.settings.focal_learning_share;
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
    pub(super) fn emission_reached(
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
