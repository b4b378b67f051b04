//! Next-event estimation: picking a light or the environment, the light sample and its
//! MIS weight against scattering, the densities a scattered hit is weighed by, and what
//! the light samples teach the light, environment and gate learners.

use glam::Vec3;
use guiding_core::environment::{EnvCell, EnvRecords, EnvSample};
use guiding_core::{DirectionalDistribution, Guide, Hit, Intersector, LightCell, LightRecords, Pcg32, Ray};

use super::counters::{PathCounters, GATE_PATH_STRIDE};
use super::method::LightSelection;
use super::tracer::{
    nee_partner_pdf, GuideClock, LightSampleRecord, NeeCells, NeeRecords, PathTracer, SurfaceInteraction,
};
use crate::color::luminance;
use crate::environment::Environment;
use crate::sampling::power_heuristic;

/// A light sample drawn at a vertex and waiting for its shadow ray: the ray, and what
/// [`PathTracer::finish_light_sample`] needs once it knows what passed.
#[derive(Clone, Copy, Debug)]
pub(super) struct PendingLightSample {
    /// The shadow ray, from the surface to the light (ending short of it) or the
    /// environment.
    pub(super) ray: Ray,
    /// Towards the light (unit).
    wi: Vec3,
    /// The BSDF times cos θ towards it.
    f: Vec3,
    /// The radiance the light sends back along `wi`.
    emitted: Vec3,
    /// The light sample's density per steradian, selection and gate in it.
    light_pdf: f32,
    /// The area light chosen and its point pdf (per steradian, before selection).
    chosen: Option<(u32, f32)>,
    /// The environment guide's cell and lobe.
    tile: Option<(EnvCell, EnvSample)>,
}

/// One light sample's result: the radiance it adds (MIS-weighted against scattering)
/// and, where it reached the light, the sample itself for learners that learn from
/// light samples (`IntegratorSettings::nee_kickstart`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct DirectLight {
    /// Reflected radiance towards `wo`, MIS-weighted.
    pub(super) radiance: Vec3,
    /// The unoccluded light sample, if any.
    pub(super) sample: Option<LightSampleRecord>,
}

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// Density with which next-event estimation produces direction `wi` towards an
    /// emitter hit at `point` (by `hit`), seen from `from`.
    /// `cell` is the light guide's cell of `from`.
    pub(super) fn light_pdf(&self, hit: &Hit, from: Vec3, cell: Option<LightCell>, point: Vec3, normal: Vec3) -> f32 {
        let Some(light) = self.scene.lights.light_at(hit.primitive, hit.barycentrics) else { return 0.0 };
        (1.0 - self.environment_choice)
            * self.selection_probability(cell, light)
            * self.scene.lights.point_pdf(light, from, point, normal)
    }

    /// Density per steradian with which next-event estimation (after choosing the
    /// environment) draws direction `wi` from `from`.
    pub(super) fn environment_pdf(&self, environment: &Environment, from: Vec3, wi: Vec3) -> f32 {
        match self.environment_guide {
            Some(guide) => guide.locate(from).map_or(0.0, |cell| guide.distribution(cell).pdf(wi)),
            None => environment.pdf(wi),
        }
    }

    /// Picks an area light for next-event estimation at a point in the light guide's
    /// `cell`: its index and probability.
    pub(super) fn select_light(&self, cell: Option<LightCell>, u: f32) -> Option<(u32, f32)> {
        let lights = &self.scene.lights;
        if lights.is_empty() {
            return None;
        }
        match (self.settings.light_selection, self.light_guide) {
            (LightSelection::Uniform, _) => {
                let count = lights.len() as u32;
                Some((((u * count as f32) as u32).min(count - 1), 1.0 / count as f32))
            }
            (LightSelection::Learned, Some(guide)) => {
                let choice = guide.select(cell?, u);
                Some((choice.light, choice.probability))
            }
            _ => Some(lights.select_by_power(u)),
        }
    }

    /// The probability [`select_light`](Self::select_light) gives `light` in `cell`.
    pub(super) fn selection_probability(&self, cell: Option<LightCell>, light: u32) -> f32 {
        match (self.settings.light_selection, self.light_guide) {
            (LightSelection::Uniform, _) => 1.0 / self.scene.lights.len() as f32,
            (LightSelection::Learned, Some(guide)) => cell.map_or(0.0, |c| guide.probability(c, light)),
            _ => self.scene.lights.power_probability(light),
        }
    }

    /// One light sample (area light or environment) at `surface`, MIS-weighted against
    /// scattering: [`draw_light_sample`](Self::draw_light_sample), its shadow ray, and
    /// [`finish_light_sample`](Self::finish_light_sample).
    pub(super) fn direct_light(
        &self,
        surface: &SurfaceInteraction,
        cells: NeeCells,
        mixture: (Option<&G::Distribution<'_>>, f32, f32),
        rng: &mut Pcg32,
        (clock, records): (&mut GuideClock, &mut NeeRecords),
        counters: &mut PathCounters,
    ) -> DirectLight {
        let Some(pending) = self.draw_light_sample(surface, cells, rng, (clock, records), counters) else {
            return DirectLight::default();
        };
        let transmittance = self.transmittance(pending.ray, counters);
        self.finish_light_sample(&pending, transmittance, surface, cells, mixture, (clock, records), counters.paths)
    }

    /// The first half of a light sample at `surface`: the light (or the environment)
    /// picked, the point or direction drawn and the BSDF there, up to the shadow ray it
    /// needs (counted in `counters`); `None` where it can bring nothing (what it taught the
    /// light and environment guides then is in `records`; `clock` times the environment
    /// guide's sample).
    // Inlined into its callers, so the pending sample it hands over stays in registers
    // rather than being written out and read back (one path at a time, nee on door: 7 %
    // of paths/s).
    #[inline(always)]
    pub(super) fn draw_light_sample(
        &self,
        surface: &SurfaceInteraction,
        cells: NeeCells,
        rng: &mut Pcg32,
        (clock, records): (&mut GuideClock, &mut NeeRecords),
        counters: &mut PathCounters,
    ) -> Option<PendingLightSample> {
        let SurfaceInteraction { point, geometric_normal, wo, ref material, ref shading } = *surface;
        let (u_choice, u_select, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
        // The gate may leave this vertex's light to the scattered direction; the number is
        // drawn only where it can, so ungated paths keep their random streams.
        let gate = cells.probability;
        if gate < 1.0 && rng.next_f32() >= gate {
            return None;
        }
        // The light chosen and its point pdf (per steradian, before selection), for learning.
        let mut chosen: Option<(u32, f32)> = None;
        // The environment guide's cell and lobe, for learning.
        let mut tile: Option<(EnvCell, EnvSample)> = None;
        let (wi, emitted, light_pdf, distance) = if u_choice < self.environment_choice {
            let environment = self.scene.environment.as_ref()?;
            match self.environment_guide {
                Some(guide) => {
                    let cell = guide.locate(point)?;
                    let s = clock.time(|| guide.distribution(cell).sample_lobe(u_select, u));
                    tile = Some((cell, s));
                    (
                        s.direction,
                        environment.radiance(s.direction),
                        gate * self.environment_choice * s.pdf,
                        f32::INFINITY,
                    )
                }
                None => {
                    let s = environment.sample(u_select, u)?;
                    (s.wi, s.radiance, gate * self.environment_choice * s.pdf, f32::INFINITY)
                }
            }
        } else {
            let (light, probability) = self.select_light(cells.light, u_select)?;
            let Some(s) = self.scene.lights.sample_point(light, point, u) else {
                self.learn_light(cells, light, (0.0, false), counters.paths, &mut records.lights);
                return None;
            };
            chosen = Some((light, s.pdf));
            (s.wi, s.radiance, gate * (1.0 - self.environment_choice) * probability * s.pdf, s.distance)
        };
        if !(light_pdf.is_finite() && light_pdf > 0.0) || emitted == Vec3::ZERO {
            if let Some((cell, sample)) = tile {
                self.learn_environment(cell, &sample, Vec3::ZERO, &mut records.environment);
            }
            return None;
        }
        let f = material.eval(shading, wo, wi);
        if f == Vec3::ZERO {
            if let Some((light, _)) = chosen {
                self.learn_light(cells, light, (0.0, false), counters.paths, &mut records.lights);
            }
            if let Some((cell, sample)) = tile {
                self.learn_environment(cell, &sample, Vec3::ZERO, &mut records.environment);
            }
            return None;
        }
        let origin = self.spawn(point, geometric_normal, wi);
        let t_max = if distance.is_finite() {
            // Stop short of the light by the spawn offset at both ends, so neither the
            // surface left nor the emitter itself (rounded far from the origin) occludes.
            let target = point + wi * distance;
            let margin = self.epsilon_at(point) + self.epsilon_at(target);
            (distance - margin).max(0.0) * (1.0 - 1e-5)
        } else {
            f32::INFINITY
        };
        counters.rays += 1;
        let ray = Ray::segment(origin, wi, 0.0, t_max);
        Some(PendingLightSample { ray, wi, f, emitted, light_pdf, chosen, tile })
    }

    /// The second half of a light sample drawn at `surface`: what passed along its
    /// shadow ray (`transmittance`: 0 blocked, 1 clear) taught to the light and
    /// environment guides (`path`: the path's number, for the gate's stride), and its
    /// radiance, MIS-weighted against the scattering `mixture` (the guide's distribution
    /// and share, the focal share).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn finish_light_sample(
        &self,
        pending: &PendingLightSample,
        transmittance: f32,
        surface: &SurfaceInteraction,
        cells: NeeCells,
        (distribution, guide_share, focal_share): (Option<&G::Distribution<'_>>, f32, f32),
        (clock, records): (&mut GuideClock, &mut NeeRecords),
        path: u64,
    ) -> DirectLight {
        let SurfaceInteraction { wo, ref material, ref shading, .. } = *surface;
        let PendingLightSample { wi, f, emitted, light_pdf, chosen, tile, .. } = *pending;
        let occluded = transmittance <= 0.0;
        if let Some((light, point_pdf)) = chosen {
            // Eq. (3)'s ‖C‖∞: the unshadowed contribution of the whole light.
            let contribution = (f * emitted / point_pdf).max_element();
            self.learn_light(cells, light, (contribution, !occluded), path, &mut records.lights);
        }
        if let Some((cell, sample)) = tile {
            self.learn_environment(cell, &sample, f * transmittance, &mut records.environment);
        }
        if occluded {
            return DirectLight::default();
        }
        let kickstart = self.kickstarts();
        let scatter_pdf = if self.settings.nee_weighs_guide {
            let guide = distribution.map(|distribution| (clock.time(|| distribution.pdf(wi)), guide_share));
            self.scatter_pdf(material, shading, wo, wi, guide, focal_share)
        } else {
            let guide_share = if distribution.is_some() { guide_share } else { 0.0 };
            nee_partner_pdf(material.pdf(shading, wo, wi), guide_share, focal_share)
        };
        let weight = power_heuristic(light_pdf, scatter_pdf);
        let radiance = f * emitted * (weight * transmittance / light_pdf);
        // Learning from the sample weighs it by the density of both strategies that draw
        // its direction (the balance heuristic's deterministic mixture), the guide's in it.
        let sample = kickstart.then(|| {
            let guide = distribution.map(|distribution| (distribution.pdf(wi), guide_share));
            LightSampleRecord {
                direction: wi,
                incident: luminance(emitted) * transmittance,
                light_pdf,
                scatter_pdf: self.scatter_pdf(material, shading, wo, wi, guide, focal_share),
            }
        });
        DirectLight { radiance, sample }
    }

    /// A vertex's cells at `point` in the light guide and the gate, with the probability
    /// that next-event estimation runs there: the gate's where it has one, else 1.
    /// Emission found by a scattered direction is weighed by MIS against this times the
    /// light pdf, so a vertex whose shadow ray the gate skipped leaves its light to that
    /// direction, unbiased.
    pub(super) fn nee_cells(&self, point: Vec3) -> NeeCells {
        let gate = self.gate.and_then(|table| Some((table, table.locate(point)?)));
        let probability = gate.map_or(1.0, |(table, cell)| table.probability(cell));
        let light = self.light_guide.and_then(|guide| guide.locate(point));
        NeeCells { light, gate: gate.map(|(_, cell)| cell), probability }
    }

    /// Teaches one shadow ray from a vertex in `cells` to `light`, its `contribution`
    /// and whether it was `unoccluded`: the light guide's V where lights are selected as
    /// learned (into the thread's `records`, learned between passes), and (in learning
    /// passes, from one path in [`GATE_PATH_STRIDE`]) the gate's count.
    pub(super) fn learn_light(
        &self,
        cells: NeeCells,
        light: u32,
        (contribution, unoccluded): (f32, bool),
        path: u64,
        records: &mut LightRecords,
    ) {
        if let (Some(guide), Some(cell)) = (self.light_guide, cells.light) {
            guide.record(records, cell, light, contribution, unoccluded);
        }
        if let (Some(gate), Some(cell)) = (self.gate, cells.gate) {
            if self.settings.learn && path % GATE_PATH_STRIDE == 0 {
                gate.record(cell, unoccluded);
            }
        }
    }

    /// Records the shadow ray of `sample` from `cell` for the environment guide (in the
    /// thread's `records`, learned between passes): `f` is the BSDF × cos θ there (zero
    /// when occluded); the sample's lobe learns ‖f·L‖∞ with L the radiance of its own light
    /// (the sun's for the sun lobe, the sky's for a tile).
    pub(super) fn learn_environment(&self, cell: EnvCell, sample: &EnvSample, f: Vec3, records: &mut EnvRecords) {
        let (Some(guide), Some(environment)) = (self.environment_guide, &self.scene.environment) else { return };
        let radiance = match &environment.sun {
            Some(sun) if Some(sample.lobe) == guide.sun_lobe() => sun.radiance(sample.direction),
            _ => environment.sky.radiance(sample.direction),
        };
        guide.record(records, cell, sample, (f * radiance).max_element());
    }
}
