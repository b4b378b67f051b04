//! The path tracing integrators: `pt` (BSDF sampling), `nee` (plus next-event estimation
//! with MIS), `guided` (Dahm & Keller's Fig. 2E: sample the guide with probability
//! p_guide, else the BSDF, weighted by the one-sample MIS mixture pdf) and `guided-nee`
//! (both, with light samples MIS-weighted against the mixture). Guided paths also learn:
//! after each path every vertex with a guide region is updated by Eq. (1).

use glam::{Vec2, Vec3};
use guiding_core::environment::{EnvCell, EnvSample};
use guiding_core::{
    DirectionalDistribution, EnvTileGuide, FocalArrival, FocalGuide, FocalRecord, GateCell, Guide, Hit,
    IntegralEstimator, Intersector, Lambertian, LightCell, LightGuide, NextEventGate, PathRecorder, Pcg32, Ray,
    SampledDirection, ScatteringFunction, StrategyArrival, StrategyShares,
};

use crate::color::luminance;
use crate::environment::Environment;
use crate::material::{Material, ShadingFrame, Surface};
use crate::sampling::power_heuristic;
use crate::scene::Scene;

/// Which estimator to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Unidirectional path tracing with BSDF sampling only.
    Pt,
    /// BSDF sampling plus next-event estimation, combined by the power heuristic.
    Nee,
    /// BSDF and guide sampling (one-sample MIS), learning online.
    Guided,
    /// Guided plus next-event estimation.
    GuidedNee,
}

impl Method {
    /// Every method, in the order the command line lists them.
    pub const ALL: [Method; 4] = [Method::Pt, Method::Nee, Method::Guided, Method::GuidedNee];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Pt => "pt",
            Method::Nee => "nee",
            Method::Guided => "guided",
            Method::GuidedNee => "guided-nee",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Whether light sources are sampled directly.
    pub fn uses_nee(self) -> bool {
        matches!(self, Method::Nee | Method::GuidedNee)
    }

    /// Whether directions are drawn from a learned guide.
    pub fn uses_guide(self) -> bool {
        matches!(self, Method::Guided | Method::GuidedNee)
    }
}

/// Settings of a path.
#[derive(Clone, Copy, Debug)]
pub struct IntegratorSettings {
    /// The estimator.
    pub method: Method,
    /// Most scattering vertices per path.
    pub max_depth: u32,
    /// Russian roulette starts after this many vertices.
    pub rr_depth: u32,
    /// Probability of sampling the guide instead of the BSDF where a guide region exists.
    pub guide_probability: f32,
    /// Only the first this many vertices of a path use the guide (locate, sample, pdf);
    /// deeper ones scatter by the BSDF alone and pass their targets back to the last
    /// guided vertex, which still learns all it would.
    pub guide_depth: u32,
    /// Probability of aiming at the focal guide's boxes instead (where it has any), in
    /// [0, 1 − guide_probability]; 0 leaves focal guiding out.
    pub focal_probability: f32,
    /// Share of paths, drawn at random, that the focal guide learns from, in (0, 1]: its
    /// records (atomic adds into shared octree leaves and selection cells, and a focal
    /// pdf per arrival) cost more than most vertices need, and a quarter of a pass's
    /// paths still teach it plenty.
    pub focal_learning_share: f32,
    /// Whether the directional guide's share is learned per region (up to
    /// `guide_probability`; where it learns 0 the guide is not even located) instead of
    /// `guide_probability` everywhere.
    pub learned_guide_share: bool,
    /// Whether the directional guide learns each direction with the density it was drawn
    /// with (`Guide::update_sampled`: the tables' entries then learn their mean over
    /// their solid angle) or without (`Guide::update`). The GPU tracer's tables learn
    /// without; the CPU renders checked against them turn this off.
    pub density_weighted_learning: bool,
    /// Whether MIS between next-event estimation and scattering weighs a direction by the
    /// scattering mixture with the guide's density in it (the power heuristic of the
    /// two strategies' actual densities, a guide pdf per light sample) or by the BSDF's
    /// share of the mixture alone (weights that still sum to one with the light's, so
    /// the image stays unbiased, and no guide lookup per light sample). The GPU tracer
    /// weighs with the guide; the CPU renders checked against its tables do too.
    pub nee_weighs_guide: bool,
    /// Whether guided paths update the guide.
    pub learn: bool,
    /// How next-event estimation picks an area light.
    pub light_selection: LightSelection,
    /// How next-event estimation samples the environment.
    pub environment_sampling: EnvironmentSampling,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        Self {
            method: Method::Nee,
            max_depth: 32,
            rr_depth: 4,
            guide_probability: 0.3,
            guide_depth: u32::MAX,
            focal_probability: 0.0,
            focal_learning_share: 0.25,
            learned_guide_share: false,
            density_weighted_learning: true,
            nee_weighs_guide: false,
            learn: true,
            light_selection: LightSelection::Power,
            environment_sampling: EnvironmentSampling::Luminance,
        }
    }
}

/// How next-event estimation samples the environment (sky and sun).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvironmentSampling {
    /// In proportion to luminance everywhere (the sun by its share of the power).
    Luminance,
    /// From an [`EnvTileGuide`]: per grid cell, tiles of the map (and the sun) by the
    /// light they were seen to bring there, with power and uniform defensive shares;
    /// learns during every pass.
    Tiles,
}

impl EnvironmentSampling {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [EnvironmentSampling; 2] = [EnvironmentSampling::Luminance, EnvironmentSampling::Tiles];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            EnvironmentSampling::Luminance => "luminance",
            EnvironmentSampling::Tiles => "tiles",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown environment sampling `{name}` (luminance, tiles)"))
    }
}

/// How next-event estimation picks one of the scene's area lights (emissive triangles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSelection {
    /// Every light equally likely.
    Uniform,
    /// In proportion to power (luminance × area).
    Power,
    /// From a [`LightGuide`] learned from shadow rays (Eq. 3), with power and uniform
    /// defensive shares; learns during every pass.
    Learned,
}

impl LightSelection {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [LightSelection; 3] = [LightSelection::Uniform, LightSelection::Power, LightSelection::Learned];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            LightSelection::Uniform => "uniform",
            LightSelection::Power => "power",
            LightSelection::Learned => "learned",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown light selection `{name}` (uniform, power, learned)"))
    }
}

/// Counters of one or many paths.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathCounters {
    /// Paths traced.
    pub paths: u64,
    /// Paths whose contribution is non-zero.
    pub nonzero_paths: u64,
    /// Closest-hit and shadow rays cast.
    pub rays: u64,
    /// Surface vertices (hits) over all paths.
    pub vertices: u64,
    /// Nanoseconds spent in guide calls on the timed paths (1 in [`TIMED_PATH_STRIDE`]).
    pub timed_guide_nanos: u64,
    /// Paths whose guide calls were timed.
    pub timed_paths: u64,
}

/// One path in this many has its guide calls timed: timing every call would cost more
/// than many of the calls themselves.
pub const TIMED_PATH_STRIDE: u64 = 64;

/// The next-event gate counts the shadow rays of one path in this many: its counters are
/// shared by every thread, and a quarter of the rays judge a cell as well (cornell 128²,
/// every path counting: training passes ≈ 15 % slower than ungated).
const GATE_PATH_STRIDE: u64 = 4;

impl PathCounters {
    /// Estimated seconds spent in guide calls over all paths, extrapolated from the
    /// timed ones.
    pub fn estimated_guide_seconds(&self) -> f64 {
        if self.timed_paths == 0 {
            return 0.0;
        }
        self.timed_guide_nanos as f64 * 1e-9 * self.paths as f64 / self.timed_paths as f64
    }
}

impl std::ops::Add for PathCounters {
    type Output = PathCounters;
    fn add(self, o: PathCounters) -> PathCounters {
        PathCounters {
            paths: self.paths + o.paths,
            nonzero_paths: self.nonzero_paths + o.nonzero_paths,
            rays: self.rays + o.rays,
            vertices: self.vertices + o.vertices,
            timed_guide_nanos: self.timed_guide_nanos + o.timed_guide_nanos,
            timed_paths: self.timed_paths + o.timed_paths,
        }
    }
}

/// What the tracer keeps beside each recorded vertex for its own learners (the guide's
/// targets themselves come from guiding-core's [`PathRecorder`]).
///
/// With next-event estimation, Q must not learn the light that next-event estimation
/// already brings: a guide that also chases the lights starves the other directions,
/// whose BSDF samples then carry mixture weights up to 1/(1-p_guide) at every bounce,
/// and those compound into fireflies. So the tracer tells the recorder, as arriving, the
/// next vertex's emission times the MIS weight it received as a BSDF/guide hit, plus the
/// light the next vertex's own next-event sample reflects back (indirect light for this
/// vertex), and as onward ∫ Q fs cos at the next vertex, whose Q was learned the same
/// way. Without next-event estimation the weights are 1 and this is exactly Eq. (1).
#[derive(Clone, Copy, Debug)]
pub struct VertexStrategies {
    /// A uniform number for the focal guide's stratified deposits (0.5 without one).
    u_record: f32,
    /// How the direction was drawn, for the focal guide's choice of its share (`None` at
    /// a delta vertex or without a focal guide).
    focal_arrival: Option<FocalArrival>,
    /// Whether the arrival's focal pdf is left to learning: where the mixture did not aim
    /// at the boxes, the pdf of `direction` under them matters only if light arrived.
    focal_pdf_pending: bool,
    /// How the direction was drawn, for the directional guide's learned share (`None`
    /// where it has none or no region here).
    guide_arrival: Option<StrategyArrival>,
}

/// Per-thread scratch space reused across paths (no allocation per path); `R` is the
/// guide's region type.
pub struct PathScratch<R> {
    path: PathRecorder<R, VertexStrategies>,
    clock: GuideClock,
}

impl<R> Default for PathScratch<R> {
    fn default() -> Self {
        Self { path: PathRecorder::default(), clock: GuideClock::default() }
    }
}

/// Accumulates the time of guide calls on the paths chosen for timing.
#[derive(Default)]
struct GuideClock {
    enabled: bool,
    nanos: u64,
}

impl GuideClock {
    fn time<T>(&mut self, call: impl FnOnce() -> T) -> T {
        if !self.enabled {
            return call();
        }
        let start = std::time::Instant::now();
        let result = call();
        self.nanos += start.elapsed().as_nanos() as u64;
        result
    }
}

/// A BSDF as the guide's integral estimate sees it: scalar fs·cos (luminance), and the
/// material's own sampler (with `u_lobe` picking its lobe).
struct ScalarBsdf<'a> {
    material: &'a Material,
    shading: &'a ShadingFrame,
    u_lobe: f32,
}

impl ScatteringFunction for ScalarBsdf<'_> {
    fn eval_cos(&self, wi: Vec3, wo: Vec3) -> f32 {
        luminance(self.material.eval(self.shading, wo, wi))
    }

    fn sample_cos(&self, wo: Vec3, u: Vec2) -> Option<SampledDirection> {
        let sample = self.material.sample(self.shading, wo, u, self.u_lobe)?;
        Some(SampledDirection { wi: sample.wi, weight: luminance(sample.weight) })
    }

    fn can_sample(&self) -> bool {
        true
    }
}

/// Traces paths through a scene, guided (for the guided methods) by any [`Guide`].
pub struct PathTracer<'a, I: Intersector, G: Guide> {
    scene: &'a Scene,
    intersector: &'a I,
    guide: Option<&'a G>,
    /// The focal guide (guided methods with a focal probability above 0).
    focal: Option<&'a FocalGuide>,
    /// The directional guide's learned share per region (`learned_guide_share`).
    guide_shares: Option<&'a StrategyShares>,
    /// The learned light selection, when `settings.light_selection` is `Learned`.
    light_guide: Option<&'a LightGuide>,
    /// The next-event gate (guided methods on the CPU).
    gate: Option<&'a NextEventGate>,
    /// The learned environment sampling, when `settings.environment_sampling` is `Tiles`.
    environment_guide: Option<&'a EnvTileGuide>,
    settings: IntegratorSettings,
    ray_epsilon: f32,
    environment_choice: f32,
    /// Whether some material has an opacity texture: rays then pass through it.
    masks: bool,
    /// The guide learns from the path's own continuation (no integral estimate at the
    /// next vertex: every vertex carries its successor's target back).
    carries_path: bool,
}

/// A vertex's cells in the light guide and the next-event gate: next-event estimation
/// there, and the MIS weight of emission found from there, read both.
#[derive(Clone, Copy, Debug, Default)]
struct NeeCells {
    light: Option<LightCell>,
    gate: Option<GateCell>,
}

/// The density MIS with next-event estimation weighs a scattered direction by (unless
/// `nee_weighs_guide`): the BSDF's share of the scattering mixture, the guide's and the
/// focal guide's terms left out. Any density both strategies share keeps their weights
/// summing to one; this one needs no guide lookup per light sample. `guide_share` is 0
/// where the vertex has no guide region.
fn nee_partner_pdf(bsdf_pdf: f32, guide_share: f32, focal_share: f32) -> f32 {
    (1.0 - guide_share - focal_share).max(0.0) * bsdf_pdf
}

/// Most masked surfaces a ray passes through before it counts as blocked.
const MAX_MASK_CROSSINGS: u32 = 64;

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// A tracer; `guide` is used by the guided methods only, `light_guide` when lights
    /// are selected as learned, `environment_guide` when the environment is sampled by
    /// tiles.
    pub fn new(
        scene: &'a Scene,
        intersector: &'a I,
        guide: Option<&'a G>,
        focal: Option<&'a FocalGuide>,
        light_guide: Option<&'a LightGuide>,
        environment_guide: Option<&'a EnvTileGuide>,
        settings: IntegratorSettings,
    ) -> Self {
        let (low, high) = scene.bounds();
        let ray_epsilon = 1e-5 * (high - low).length().max(f32::MIN_POSITIVE);
        let environment_choice = match (scene.environment.is_some(), scene.lights.is_empty()) {
            (true, true) => 1.0,
            (true, false) => 0.5,
            (false, _) => 0.0,
        };
        let guide = if settings.method.uses_guide() { guide } else { None };
        let focal = focal.filter(|_| settings.method.uses_guide() && settings.focal_probability > 0.0);
        let light_guide = light_guide.filter(|_| settings.light_selection == LightSelection::Learned);
        let environment_guide =
            environment_guide.filter(|_| settings.environment_sampling == EnvironmentSampling::Tiles);
        let masks = scene.has_masks();
        let carries_path = guide.is_some_and(|g| g.update_rule().integral == IntegralEstimator::PathContinuation);
        Self {
            scene,
            intersector,
            guide,
            focal,
            guide_shares: None,
            light_guide,
            gate: None,
            environment_guide,
            settings,
            ray_epsilon,
            environment_choice,
            masks,
            carries_path,
        }
    }

    /// The tracer with a next-event gate (used where the method estimates next-event
    /// light).
    pub fn with_gate(mut self, gate: Option<&'a NextEventGate>) -> Self {
        self.gate = gate.filter(|_| self.settings.method.uses_nee());
        self
    }

    /// The tracer with the directional guide's learned shares (used where
    /// `learned_guide_share` is set and a guide is there).
    pub fn with_guide_shares(mut self, shares: Option<&'a StrategyShares>) -> Self {
        self.guide_shares = shares.filter(|_| self.guide.is_some() && self.settings.learned_guide_share);
        self
    }

    /// Offset of a ray leaving `point` on the side of `normal` that `direction` points to:
    /// relative to the scene size and to the magnitude of the coordinates.
    fn spawn(&self, point: Vec3, normal: Vec3, direction: Vec3) -> Vec3 {
        let side = if normal.dot(direction) >= 0.0 { 1.0 } else { -1.0 };
        point + normal * (side * self.epsilon_at(point))
    }

    /// How far from a surface at `point` a ray must start or stop not to hit it again:
    /// the scene-relative epsilon plus a few f32 steps of the coordinates there.
    fn epsilon_at(&self, point: Vec3) -> f32 {
        self.ray_epsilon + 1e-6 * point.abs().max_element()
    }

    /// The closest surface along `ray` that the ray stops at, with its textured material:
    /// a masked surface lets the ray pass with probability 1 − opacity (its hit is
    /// skipped and tracing goes on beyond it).
    fn next_surface(&self, mut ray: Ray, rng: &mut Pcg32, counters: &mut PathCounters) -> Option<(Hit, Material)> {
        for _ in 0..MAX_MASK_CROSSINGS {
            let hit = self.intersector.intersect(&ray)?;
            let (material, opacity) = self.scene.material_at(hit.primitive, hit.barycentrics);
            if opacity >= 1.0 || rng.next_f32() < opacity {
                return Some((hit, material));
            }
            let point = self.scene.triangles[hit.primitive as usize].point(hit.barycentrics);
            let normal = self.scene.normals[hit.primitive as usize];
            ray = Ray { origin: self.spawn(point, normal, ray.direction), t_max: ray.t_max - hit.t, ..ray };
            counters.rays += 1;
        }
        None
    }

    /// The share of light that passes along the segment `ray`: 0 when something opaque
    /// blocks it, else the product of (1 − opacity) of the masked surfaces it crosses.
    fn transmittance(&self, mut ray: Ray, counters: &mut PathCounters) -> f32 {
        if !self.masks {
            return if self.intersector.occluded(&ray) { 0.0 } else { 1.0 };
        }
        let mut transmittance = 1.0;
        for _ in 0..MAX_MASK_CROSSINGS {
            let Some(hit) = self.intersector.intersect(&ray) else { return transmittance };
            let (_, opacity) = self.scene.material_at(hit.primitive, hit.barycentrics);
            transmittance *= 1.0 - opacity;
            if transmittance <= 0.0 {
                return 0.0;
            }
            let point = self.scene.triangles[hit.primitive as usize].point(hit.barycentrics);
            let normal = self.scene.normals[hit.primitive as usize];
            let origin = self.spawn(point, normal, ray.direction);
            ray = Ray { origin, t_max: ray.t_max - (origin - ray.origin).length(), ..ray };
            counters.rays += 1;
        }
        0.0
    }

    /// Density with which next-event estimation produces direction `wi` towards an
    /// emitter hit at `point` (by `hit`), seen from `from`.
    /// `cell` is the light guide's cell of `from`.
    fn light_pdf(&self, hit: &Hit, from: Vec3, cell: Option<LightCell>, point: Vec3, normal: Vec3) -> f32 {
        let Some(light) = self.scene.lights.light_at(hit.primitive, hit.barycentrics) else { return 0.0 };
        (1.0 - self.environment_choice)
            * self.selection_probability(cell, light)
            * self.scene.lights.point_pdf(light, from, point, normal)
    }

    /// Density per steradian with which next-event estimation (after choosing the
    /// environment) draws direction `wi` from `from`.
    fn environment_pdf(&self, environment: &Environment, from: Vec3, wi: Vec3) -> f32 {
        match self.environment_guide {
            Some(guide) => guide.cell(from).map_or(0.0, |cell| guide.distribution(cell).pdf(wi)),
            None => environment.pdf(wi),
        }
    }

    /// Picks an area light for next-event estimation at a point in the light guide's
    /// `cell`: its index and probability.
    fn select_light(&self, cell: Option<LightCell>, u: f32) -> Option<(u32, f32)> {
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
    fn selection_probability(&self, cell: Option<LightCell>, light: u32) -> f32 {
        match (self.settings.light_selection, self.light_guide) {
            (LightSelection::Uniform, _) => 1.0 / self.scene.lights.len() as f32,
            (LightSelection::Learned, Some(guide)) => cell.map_or(0.0, |c| guide.probability(c, light)),
            _ => self.scene.lights.power_probability(light),
        }
    }

    /// Radiance arriving along `ray` (one sample), adding its counters to `counters`.
    pub fn radiance(
        &self,
        mut ray: Ray,
        rng: &mut Pcg32,
        scratch: &mut PathScratch<G::Region>,
        counters: &mut PathCounters,
    ) -> Vec3 {
        let settings = &self.settings;
        let learning = settings.learn && (self.guide.is_some() || self.focal.is_some());
        scratch.path.clear();
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
        for depth in 0..settings.max_depth {
            counters.rays += 1;
            let next = self.next_surface(ray, rng, counters);
            if let Some((hit, _)) = &next {
                scratch.path.reached(hit.t);
            }
            let Some((hit, material)) = next else {
                if let Some(environment) = &self.scene.environment {
                    let emitted = environment.radiance(ray.direction);
                    let weight = match previous {
                        Some((from, pdf, false, cells)) if settings.method.uses_nee() => power_heuristic(
                            pdf,
                            self.next_event_probability(cells.gate)
                                * self.environment_choice
                                * self.environment_pdf(environment, from, ray.direction),
                        ),
                        _ => 1.0,
                    };
                    radiance += throughput * emitted * weight;
                    scratch.path.arrive(weight * luminance(emitted));
                }
                break;
            };
            counters.vertices += 1;
            let material = &material;
            let triangle = &self.scene.triangles[hit.primitive as usize];
            let point = triangle.point(hit.barycentrics);
            let geometric_normal = self.scene.normals[hit.primitive as usize];
            let wo = -ray.direction;

            // Emission from the front face.
            if material.is_emissive() && geometric_normal.dot(wo) > 0.0 {
                let weight = match previous {
                    Some((from, pdf, false, cells)) if settings.method.uses_nee() => power_heuristic(
                        pdf,
                        self.next_event_probability(cells.gate)
                            * self.light_pdf(&hit, from, cells.light, point, geometric_normal),
                    ),
                    _ => 1.0,
                };
                radiance += throughput * material.emission * weight;
                scratch.path.arrive(weight * luminance(material.emission));
            }
            let shading_normal = self.scene.shading_normal(hit.primitive, hit.barycentrics);
            let shading = material.shading_frame(geometric_normal, shading_normal, wo);
            let normal = shading.frame.normal;
            let delta = material.is_delta();
            // The guide's share here: fixed, or learned per region (where it learned 0 the
            // guide is not even located, except to keep learning).
            let guides_here = self.guide.is_some() && !delta && depth < settings.guide_depth;
            let guide_share = match self.guide_shares {
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
                        Surface::Diffuse { albedo } => {
                            guide.estimate_integral(region, wo, &Lambertian { normal, albedo: luminance(albedo) }, u)
                        }
                        _ => {
                            let bsdf = ScalarBsdf { material, shading: &shading, u_lobe };
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
            // The focal guide's share of the scattering here (0 where it has no boxes, and
            // left out altogether in frozen passes where no region aims at them).
            let focal = self.focal.filter(|f| !delta && if learning { !f.boxes().is_empty() } else { f.aims() });
            let focal_share = focal.map_or(0.0, |f| f.selection_probability(point).min(settings.focal_probability));
            // Learning measures the boxes' share from every direction, sampled by them or not.
            let focal = focal.filter(|_| focal_share > 0.0 || learning);
            // Next-event estimation, and the cells it and the MIS weight of emission found
            // from here share.
            let nee_cells = if settings.method.uses_nee() && !delta {
                NeeCells {
                    light: self.light_guide.and_then(|guide| guide.cell(point)),
                    gate: self.gate.and_then(|gate| gate.cell(point)),
                }
            } else {
                NeeCells::default()
            };
            if settings.method.uses_nee() && !delta {
                let direct = self.direct_light(
                    material,
                    &shading,
                    (point, nee_cells),
                    geometric_normal,
                    wo,
                    (distribution.as_ref(), guide_share, focal_share),
                    rng,
                    clock,
                    counters,
                );
                radiance += throughput * direct;
                scratch.path.arrive(luminance(direct));
            }

            // Russian roulette, decided before the direction is drawn: a survival that
            // depended on the direction (through its fs·cos/pdf) would make the traced
            // directions, which are all the guide learns from, follow p·survival instead
            // of the p they are recorded with.
            let mut survival = 1.0;
            if depth + 1 >= settings.rr_depth {
                survival = roulette_throughput.max_element().min(0.95);
                if survival <= 0.0 || rng.next_f32() >= survival {
                    break;
                }
                throughput /= survival;
                roulette_throughput /= survival;
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
                let Some(s) = material.sample(&shading, wo, u, u_lobe) else { break };
                (s.wi, s.weight, s.weight, s.pdf, s.pdf, true)
            } else {
                let guide_probability = if distribution.is_some() { guide_share } else { 0.0 };
                // A direction drawn from a guide comes with that guide's pdf: not evaluated twice.
                let (wi, f, guide_pdf, focal_pdf) = match (&distribution, focal) {
                    (_, Some(focal)) if u_choice < focal_share && focal_share > 0.0 => {
                        let u_point = Vec3::new(u_choice / focal_share, u.x, u.y);
                        let Some(s) = clock.time(|| focal.sample(point, u_lobe, u_point)) else { break };
                        (s.direction, material.eval(&shading, wo, s.direction), None, Some(s.pdf))
                    }
                    (Some(distribution), _) if u_choice < focal_share + guide_probability => {
                        let s = clock.time(|| distribution.sample(u));
                        (s.direction, material.eval(&shading, wo, s.direction), Some(s.pdf), None)
                    }
                    _ => {
                        let Some(s) = material.sample(&shading, wo, u, u_lobe) else { break };
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
                let bsdf_pdf = material.pdf(&shading, wo, wi);
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
                    guide_arrival = Some(StrategyArrival { point, integrand, pdf, strategy_pdf, bsdf_pdf, selection });
                }
                if focal.is_some() {
                    // The integrand is filled in once the path knows what arrived.
                    let integrand = luminance(f);
                    let selection = focal_share;
                    focal_arrival = Some(FocalArrival { point, integrand, pdf, focal_pdf, bsdf_pdf, selection });
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
        if radiance.max_element() > 0.0 {
            counters.nonzero_paths += 1;
        }
        if learning {
            // Drawn after the path, so the share leaves the path's own numbers alone.
            let focal_learns = self.focal.is_some() && rng.next_f32() < settings.focal_learning_share;
            let path = &scratch.path;
            scratch.clock.time(|| self.learn_from_path(path, focal_learns));
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
    fn scatter_pdf(
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
    fn mix_pdf(&self, bsdf_pdf: f32, guide: Option<(f32, f32)>, focal_share: f32) -> f32 {
        match guide {
            Some((guide_pdf, p)) => p * guide_pdf + (1.0 - p - focal_share) * bsdf_pdf,
            None => (1.0 - focal_share) * bsdf_pdf,
        }
    }

    /// One light sample (area light or environment), MIS-weighted against scattering.
    #[allow(clippy::too_many_arguments)]
    fn direct_light(
        &self,
        material: &Material,
        shading: &ShadingFrame,
        (point, cells): (Vec3, NeeCells),
        geometric_normal: Vec3,
        wo: Vec3,
        (distribution, guide_share, focal_share): (Option<&G::Distribution<'_>>, f32, f32),
        rng: &mut Pcg32,
        clock: &mut GuideClock,
        counters: &mut PathCounters,
    ) -> Vec3 {
        let (u_choice, u_select, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
        // The gate may leave this vertex's light to the scattered direction; the number is
        // drawn only where it can, so ungated paths keep their random streams.
        let gate = self.next_event_probability(cells.gate);
        if gate < 1.0 && rng.next_f32() >= gate {
            return Vec3::ZERO;
        }
        // The light chosen and its point pdf (per steradian, before selection), for learning.
        let mut chosen: Option<(u32, f32)> = None;
        // The environment guide's cell and lobe, for learning.
        let mut tile: Option<(EnvCell, EnvSample)> = None;
        let (wi, emitted, light_pdf, distance) = if u_choice < self.environment_choice {
            let Some(environment) = &self.scene.environment else { return Vec3::ZERO };
            match self.environment_guide {
                Some(guide) => {
                    let Some(cell) = guide.cell(point) else { return Vec3::ZERO };
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
                    let Some(s) = environment.sample(u_select, u) else { return Vec3::ZERO };
                    (s.wi, s.radiance, gate * self.environment_choice * s.pdf, f32::INFINITY)
                }
            }
        } else {
            let Some((light, probability)) = self.select_light(cells.light, u_select) else { return Vec3::ZERO };
            let Some(s) = self.scene.lights.sample_point(light, point, u) else {
                self.learn_light(cells, light, 0.0, false, counters.paths);
                return Vec3::ZERO;
            };
            chosen = Some((light, s.pdf));
            (s.wi, s.radiance, gate * (1.0 - self.environment_choice) * probability * s.pdf, s.distance)
        };
        if !(light_pdf.is_finite() && light_pdf > 0.0) || emitted == Vec3::ZERO {
            if let Some((cell, sample)) = tile {
                self.learn_environment(cell, &sample, Vec3::ZERO);
            }
            return Vec3::ZERO;
        }
        let f = material.eval(shading, wo, wi);
        if f == Vec3::ZERO {
            if let Some((light, _)) = chosen {
                self.learn_light(cells, light, 0.0, false, counters.paths);
            }
            if let Some((cell, sample)) = tile {
                self.learn_environment(cell, &sample, Vec3::ZERO);
            }
            return Vec3::ZERO;
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
        let transmittance = self.transmittance(Ray::segment(origin, wi, 0.0, t_max), counters);
        let occluded = transmittance <= 0.0;
        if let Some((light, point_pdf)) = chosen {
            // Eq. (3)'s ‖C‖∞: the unshadowed contribution of the whole light.
            self.learn_light(cells, light, (f * emitted / point_pdf).max_element(), !occluded, counters.paths);
        }
        if let Some((cell, sample)) = tile {
            self.learn_environment(cell, &sample, f * transmittance);
        }
        if occluded {
            return Vec3::ZERO;
        }
        let scatter_pdf = if self.settings.nee_weighs_guide {
            let guide = distribution.map(|distribution| (clock.time(|| distribution.pdf(wi)), guide_share));
            self.scatter_pdf(material, shading, wo, wi, guide, focal_share)
        } else {
            let guide_share = if distribution.is_some() { guide_share } else { 0.0 };
            nee_partner_pdf(material.pdf(shading, wo, wi), guide_share, focal_share)
        };
        let weight = power_heuristic(light_pdf, scatter_pdf);
        f * emitted * (weight * transmittance / light_pdf)
    }

    /// The probability that next-event estimation runs at `point`: the light guide's
    /// gate where it has one, else 1. Emission found by a scattered direction is weighed
    /// by MIS against this times the light pdf, so a vertex whose shadow ray the gate
    /// skipped leaves its light to that direction, unbiased.
    fn next_event_probability(&self, cell: Option<GateCell>) -> f32 {
        match (self.gate, cell) {
            (Some(gate), Some(cell)) => gate.probability(cell),
            _ => 1.0,
        }
    }

    /// Teaches one shadow ray from a vertex in `cells` to `light`: the light guide's V
    /// where lights are selected as learned, and (in learning passes, from one path in
    /// [`GATE_PATH_STRIDE`]) the gate's count.
    fn learn_light(&self, cells: NeeCells, light: u32, contribution: f32, unoccluded: bool, path: u64) {
        if let (Some(guide), Some(cell)) = (self.light_guide, cells.light) {
            guide.update(cell, light, contribution, unoccluded);
        }
        if let (Some(gate), Some(cell)) = (self.gate, cells.gate) {
            if self.settings.learn && path % GATE_PATH_STRIDE == 0 {
                gate.record(cell, unoccluded);
            }
        }
    }

    /// Teaches the environment guide the shadow ray of `sample` from `cell`: `f` is the
    /// BSDF × cos θ there (zero when occluded); the sample's lobe learns ‖f·L‖∞ with L the
    /// radiance of its own light (the sun's for the sun lobe, the sky's for a tile).
    fn learn_environment(&self, cell: EnvCell, sample: &EnvSample, f: Vec3) {
        let (Some(guide), Some(environment)) = (self.environment_guide, &self.scene.environment) else { return };
        let radiance = match &environment.sun {
            Some(sun) if Some(sample.lobe) == guide.sun_lobe() => sun.radiance(sample.direction),
            _ => environment.sky.radiance(sample.direction),
        };
        guide.update(cell, sample, (f * radiance).max_element());
    }

    /// Teaches the finished path to every learner: the directional guide its Eq. (1)
    /// targets (from the recorder), the learned shares and the focal guide what arrived
    /// along each direction. Rejected targets are counted by the guide itself (its
    /// `stats()`).
    fn learn_from_path(&self, path: &PathRecorder<G::Region, VertexStrategies>, focal_learns: bool) {
        if let Some(guide) = self.guide {
            path.learn(guide, self.settings.density_weighted_learning);
        }
        let focal = self.focal.filter(|_| focal_learns);
        if self.guide_shares.is_none() && focal.is_none() {
            return;
        }
        for (vertex, target) in path.targets() {
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

    /// Image-space jitter plus camera ray for pixel (x, y).
    pub fn camera_ray(&self, x: u32, y: u32, rng: &mut Pcg32) -> Ray {
        let jitter = rng.next_vec2();
        self.scene.camera.ray(Vec2::new(x as f32 + jitter.x, y as f32 + jitter.y))
    }
}
