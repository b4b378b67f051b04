//! The path tracer: what it holds (the scene, the intersector, the guide and every
//! learner), how its rays leave surfaces and pass opacity masks, and the per-thread
//! scratch space of its paths.

use glam::{Vec2, Vec3};
use guiding_core::environment::EnvRecords;
use guiding_core::{
    EfficiencyRoulette, EnvTileGuide, FocalArrival, FocalGuide, GateCell, Guide, Hit, IntegralEstimator, Intersector,
    LightCell, LightGuide, LightRecords, NextEventGate, PathRecorder, Pcg32, Ray, RouletteCell, RouletteImage,
    SampledDirection, ScatteringFunction, StrategyArrival, StrategyShares,
};

use super::counters::PathCounters;
use super::method::Method;
use super::settings::IntegratorSettings;
use crate::color::luminance;
use crate::material::{Material, ShadingFrame};
use crate::scene::Scene;

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
    pub(super) u_record: f32,
    /// How the direction was drawn, for the focal guide's choice of its share (`None` at
    /// a delta vertex or without a focal guide).
    pub(super) focal_arrival: Option<FocalArrival>,
    /// Whether the arrival's focal pdf is left to learning: where the mixture did not aim
    /// at the boxes, the pdf of `direction` under them matters only if light arrived.
    pub(super) focal_pdf_pending: bool,
    /// How the direction was drawn, for the directional guide's learned share (`None`
    /// where it has none or no region here).
    pub(super) guide_arrival: Option<StrategyArrival>,
}

/// One thread's records of next-event estimation's learners in a pass, each added to its
/// guide between passes instead of updating it at every shadow ray.
#[derive(Clone, Debug, Default)]
pub struct NeeRecords {
    /// For [`LightGuide::splat`](guiding_core::LightGuide::splat).
    pub lights: LightRecords,
    /// For [`EnvTileGuide::splat`](guiding_core::EnvTileGuide::splat).
    pub environment: EnvRecords,
}

/// Per-thread scratch space reused across paths (no allocation per path); `R` is the
/// guide's region type, `B` its per-thread records ([`Guide::Records`]).
pub struct PathScratch<R, B = ()> {
    /// The directional guide's records of this thread's paths in the pass, for
    /// [`Guide::splat`] after it.
    pub records: B,
    /// The light and environment guides' records of this thread's shadow rays in the
    /// pass, splatted after it.
    pub nee_records: NeeRecords,
    pub(super) path: PathRecorder<R, VertexStrategies>,
    /// The path's unoccluded light samples, where it learns from them
    /// (`IntegratorSettings::nee_kickstart`).
    pub(super) light_samples: Vec<LearnedLightSample<R>>,
    /// The path's vertices as the efficiency-aware roulette learns from them.
    pub(super) roulette_vertices: Vec<RouletteVertex>,
    /// Copies of the path split off and not yet traced.
    pub(super) branches: Vec<Branch>,
    pub(super) clock: GuideClock,
    /// The lane loop's paths and batches ([`PathTracer::radiance_in_lanes`]).
    pub lanes: super::LaneScratch,
}

impl<R, B: Default> Default for PathScratch<R, B> {
    fn default() -> Self {
        Self {
            records: B::default(),
            nee_records: NeeRecords::default(),
            path: PathRecorder::default(),
            light_samples: Vec::new(),
            roulette_vertices: Vec::new(),
            branches: Vec::new(),
            clock: GuideClock::default(),
            lanes: super::LaneScratch::default(),
        }
    }
}

/// A copy of a path split at a vertex, waiting to re-enter it: the vertex's incoming ray,
/// the copy's share of the throughput (and of the roulette's throughput), and the
/// vertex's depth.
#[derive(Clone, Copy, Debug)]
pub(super) struct Branch {
    pub(super) ray: Ray,
    pub(super) throughput: Vec3,
    pub(super) roulette_throughput: Vec3,
    pub(super) depth: u32,
}

/// A vertex as the efficiency-aware roulette learns from it once its path is done: what
/// the path had gathered before the vertex's next-event estimation and after it, and
/// the throughput that arrived there (luminance).
#[derive(Clone, Copy, Debug)]
pub(super) struct RouletteVertex {
    pub(super) cell: RouletteCell,
    pub(super) throughput: f32,
    pub(super) before_light_sample: f32,
    pub(super) after_light_sample: f32,
    /// The path's rays so far, at the roulette's decision here.
    pub(super) rays: u64,
}

/// An unoccluded light sample as a record of incident radiance.
#[derive(Clone, Copy, Debug)]
pub(super) struct LightSampleRecord {
    /// Towards the light (unit).
    pub(super) direction: Vec3,
    /// Incident radiance (luminance) along `direction`, unweighted.
    pub(super) incident: f32,
    /// Density of the light sample, per steradian.
    pub(super) light_pdf: f32,
    /// Density with which scattering draws `direction`, per steradian.
    pub(super) scatter_pdf: f32,
}

/// A light sample kept for learning at the end of its path.
#[derive(Clone, Copy, Debug)]
pub(super) struct LearnedLightSample<R> {
    /// The guide's region at the vertex it left from.
    pub(super) region: R,
    /// The sample.
    pub(super) record: LightSampleRecord,
}

/// Accumulates the time of guide calls on the paths chosen for timing.
#[derive(Default)]
pub(super) struct GuideClock {
    pub(super) enabled: bool,
    pub(super) nanos: u64,
}

impl GuideClock {
    pub(super) fn time<T>(&mut self, call: impl FnOnce() -> T) -> T {
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
pub(super) struct ScalarBsdf<'a> {
    pub(super) material: &'a Material,
    pub(super) shading: &'a ShadingFrame,
    pub(super) u_lobe: f32,
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
    pub(super) scene: &'a Scene,
    pub(super) intersector: &'a I,
    pub(super) guide: Option<&'a G>,
    /// The focal guide (guided methods with a focal probability above 0).
    pub(super) focal: Option<&'a FocalGuide>,
    /// The directional guide's learned share per region (`learned_guide_share`).
    pub(super) guide_shares: Option<&'a StrategyShares>,
    /// The learned light selection, when `settings.light_selection` is `Learned`.
    pub(super) light_guide: Option<&'a LightGuide>,
    /// The next-event gate (guided methods on the CPU).
    pub(super) gate: Option<&'a NextEventGate>,
    /// The learned environment sampling, when `settings.environment_sampling` is `Tiles`.
    pub(super) environment_guide: Option<&'a EnvTileGuide>,
    /// The efficiency-aware roulette's learned cells, when `settings.roulette` is
    /// `Efficiency`.
    pub(super) roulette: Option<&'a EfficiencyRoulette>,
    /// The image the roulette weighs paths against (its `pixel` set per path).
    pub(super) roulette_image: RouletteImage,
    pub(super) settings: IntegratorSettings,
    /// The diagonal of the scene's bounds, scene units.
    pub(super) extent: f32,
    pub(super) ray_epsilon: f32,
    pub(super) environment_choice: f32,
    /// Whether some material has an opacity texture: rays then pass through it.
    pub(super) masks: bool,
    /// The guide learns from the path's own continuation (no integral estimate at the
    /// next vertex: every vertex carries its successor's target back).
    pub(super) carries_path: bool,
    /// bdpt's connection roulette threshold (luminance of a weighted contribution; 0:
    /// every connection traced): see [`with_connection_threshold`](Self::with_connection_threshold).
    pub(super) connection_threshold: f32,
    /// W, guiding the light subpaths of bdpt-guided and vpl-guided (see
    /// [`with_importance_guide`](Self::with_importance_guide)).
    pub(super) importance: Option<&'a G>,
    /// Q and W locate alike (see [`Guide::locates_alike`]): a vertex locates once for both.
    pub(super) shared_regions: bool,
}

// Every field is a reference or a number: a copy costs nothing, and the guides it
// borrows need not be cloneable.
impl<I: Intersector, G: Guide> Clone for PathTracer<'_, I, G> {
    fn clone(&self) -> Self {
        Self { ..*self }
    }
}

/// The surface a path reached, built once per hit: where it is, which way it faces,
/// what it is made of there, and the frame it shades in as seen from `wo`.
pub(super) struct SurfaceInteraction {
    /// The hit point (scene units).
    pub(super) point: Vec3,
    /// The triangle's unit geometric normal, as its winding gives it.
    pub(super) geometric_normal: Vec3,
    /// Unit direction back along the ray that arrived.
    pub(super) wo: Vec3,
    /// The material there, textures evaluated.
    pub(super) material: Material,
    /// The shading frame seen from `wo`.
    pub(super) shading: ShadingFrame,
}

/// A vertex's cells in the light guide and the next-event gate, and the gate's
/// probability there: next-event estimation there, and the MIS weight of emission found
/// from there, read them.
#[derive(Clone, Copy, Debug)]
pub(super) struct NeeCells {
    pub(super) light: Option<LightCell>,
    pub(super) gate: Option<GateCell>,
    /// The probability that next-event estimation runs here (1 without a gate).
    pub(super) probability: f32,
}

impl Default for NeeCells {
    fn default() -> Self {
        Self { light: None, gate: None, probability: 1.0 }
    }
}

/// The density MIS with next-event estimation weighs a scattered direction by (unless
/// `nee_weighs_guide`): the BSDF's share of the scattering mixture, the guide's and the
/// focal guide's terms left out. Any density both strategies share keeps their weights
/// summing to one; this one needs no guide lookup per light sample. `guide_share` is 0
/// where the vertex has no guide region.
pub(super) fn nee_partner_pdf(bsdf_pdf: f32, guide_share: f32, focal_share: f32) -> f32 {
    (1.0 - guide_share - focal_share).max(0.0) * bsdf_pdf
}

/// Most masked surfaces a ray passes through before it counts as blocked.
pub(super) const MAX_MASK_CROSSINGS: u32 = 64;

impl<'a, I: Intersector, G: Guide> PathTracer<'a, I, G> {
    /// A tracer of `scene` with no learner: [`with_guide`](Self::with_guide) and the other
    /// `with_*` builders add the ones its method uses (`render::Learners::used_by`
    /// decides which), and it uses every one it is given: the guide at the guided
    /// vertices, the light guide to select lights, the environment guide to sample the
    /// environment. What it derives from the scene (its size, its lights, its masks) is
    /// computed here, once: a render builds one tracer and copies it for every pass.
    pub fn new(scene: &'a Scene, intersector: &'a I, settings: IntegratorSettings) -> Self {
        let (low, high) = scene.bounds();
        let extent = (high - low).length();
        let ray_epsilon = 1e-5 * extent.max(f32::MIN_POSITIVE);
        let environment_choice = match (scene.environment.is_some(), scene.lights.is_empty()) {
            (true, true) => 1.0,
            (true, false) => 0.5,
            (false, _) => 0.0,
        };
        Self {
            scene,
            intersector,
            guide: None,
            focal: None,
            guide_shares: None,
            light_guide: None,
            gate: None,
            environment_guide: None,
            roulette: None,
            roulette_image: RouletteImage { pixel: 0.0, relative_variance: 0.0, path_cost: 0.0 },
            settings,
            extent,
            ray_epsilon,
            environment_choice,
            masks: scene.has_masks(),
            carries_path: false,
            connection_threshold: 0.0,
            importance: None,
            shared_regions: false,
        }
    }

    /// The tracer with the directional guide Q, sampled at the guided vertices.
    pub fn with_guide(mut self, guide: Option<&'a G>) -> Self {
        self.guide = guide;
        self.carries_path = guide.is_some_and(|g| g.update_rule().integral == IntegralEstimator::PathContinuation);
        self.shared_regions = self.guides_locate_alike();
        self
    }

    /// The tracer with the focal guide (guided methods with a focal probability above 0).
    pub fn with_focal_guide(mut self, focal: Option<&'a FocalGuide>) -> Self {
        self.focal = focal;
        self
    }

    /// The tracer with the learned light selection.
    pub fn with_light_guide(mut self, light_guide: Option<&'a LightGuide>) -> Self {
        self.light_guide = light_guide;
        self
    }

    /// The tracer with the learned environment sampling.
    pub fn with_environment_guide(mut self, environment_guide: Option<&'a EnvTileGuide>) -> Self {
        self.environment_guide = environment_guide;
        self
    }

    /// The tracer with other settings (a pass that learns or not), the same scene.
    pub fn with_settings(mut self, settings: IntegratorSettings) -> Self {
        self.settings = settings;
        self
    }

    /// The settings it traces with.
    pub fn settings(&self) -> &IntegratorSettings {
        &self.settings
    }

    /// The diagonal of the scene's bounds, scene units.
    pub fn scene_extent(&self) -> f32 {
        self.extent
    }

    /// The tracer with W, the importance the light subpaths of bdpt-guided and
    /// vpl-guided learn and are guided by.
    pub fn with_importance_guide(mut self, importance: Option<&'a G>) -> Self {
        self.importance = importance;
        self.shared_regions = self.guides_locate_alike();
        self
    }

    /// Whether Q and W are both here and locate alike.
    fn guides_locate_alike(&self) -> bool {
        matches!((self.guide, self.importance), (Some(q), Some(w)) if q.locates_alike(w))
    }

    /// W, where the tracer has it.
    pub fn importance_guide(&self) -> Option<&'a G> {
        self.importance
    }

    /// The tracer with bdpt's connection roulette: a connection whose weighted, unblocked
    /// contribution has luminance c below `threshold` traces its shadow ray with
    /// probability c / `threshold` only, weighted by the inverse (0 or less: all traced).
    pub fn with_connection_threshold(mut self, threshold: f32) -> Self {
        self.connection_threshold = if threshold.is_finite() { threshold.max(0.0) } else { 0.0 };
        self
    }

    /// The tracer with a next-event gate, for methods that estimate next-event light.
    pub fn with_gate(mut self, gate: Option<&'a NextEventGate>) -> Self {
        self.gate = gate;
        self
    }

    /// The tracer with the efficiency-aware roulette's learned cells, the image's relative
    /// variance per sample so far (mean over pixels of a sample's variance over the squared
    /// pixel, as relMSE weighs it) and the rays a camera path cast on average.
    pub fn with_roulette(
        mut self,
        roulette: Option<&'a EfficiencyRoulette>,
        relative_variance: f32,
        path_rays: f32,
    ) -> Self {
        self.roulette = roulette;
        self.roulette_image = RouletteImage { pixel: 0.0, relative_variance, path_cost: path_rays };
        self
    }

    /// The tracer with the directional guide's learned shares, where it has the guide.
    pub fn with_guide_shares(mut self, shares: Option<&'a StrategyShares>) -> Self {
        self.guide_shares = shares;
        self
    }

    /// Whether this pass runs next-event estimation only to learn from it
    /// ([`IntegratorSettings::nee_kickstart`]).
    pub(super) fn kickstarts(&self) -> bool {
        self.settings.nee_kickstart
            && self.settings.learn
            && self.settings.method == Method::Guided
            && (self.guide.is_some() || self.focal.is_some())
    }

    /// Whether this pass estimates next-event light (the method's own, or to learn).
    pub(super) fn estimates_nee(&self) -> bool {
        self.settings.method.uses_nee() || self.kickstarts()
    }

    /// Offset of a ray leaving `point` on the side of `normal` that `direction` points to:
    /// relative to the scene size and to the magnitude of the coordinates.
    pub(super) fn spawn(&self, point: Vec3, normal: Vec3, direction: Vec3) -> Vec3 {
        let side = if normal.dot(direction) >= 0.0 { 1.0 } else { -1.0 };
        point + normal * (side * self.epsilon_at(point))
    }

    /// How far from a surface at `point` a ray must start or stop not to hit it again:
    /// the scene-relative epsilon plus a few f32 steps of the coordinates there.
    pub(super) fn epsilon_at(&self, point: Vec3) -> f32 {
        self.ray_epsilon + 1e-6 * point.abs().max_element()
    }

    /// The closest surface along `ray` that the ray stops at, with its textured material:
    /// a masked surface lets the ray pass with probability 1 − opacity (its hit is
    /// skipped and tracing goes on beyond it).
    pub(super) fn next_surface(
        &self,
        mut ray: Ray,
        rng: &mut Pcg32,
        counters: &mut PathCounters,
    ) -> Option<(Hit, Material)> {
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
    pub(super) fn transmittance(&self, mut ray: Ray, counters: &mut PathCounters) -> f32 {
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

    /// The interaction at `hit`, reached along `direction`, with its `material`.
    pub(super) fn interaction(&self, hit: &Hit, material: Material, direction: Vec3) -> SurfaceInteraction {
        let primitive = hit.primitive as usize;
        let point = self.scene.triangles[primitive].point(hit.barycentrics);
        let geometric_normal = self.scene.normals[primitive];
        let wo = -direction;
        let shading_normal = self.scene.shading_normal(hit.primitive, hit.barycentrics);
        let shading = material.shading_frame(geometric_normal, shading_normal, wo);
        SurfaceInteraction { point, geometric_normal, wo, material, shading }
    }

    /// Image-space jitter plus camera ray for pixel (x, y).
    pub fn camera_ray(&self, x: u32, y: u32, rng: &mut Pcg32) -> Ray {
        let jitter = rng.next_vec2();
        self.scene.camera.ray(Vec2::new(x as f32 + jitter.x, y as f32 + jitter.y))
    }
}
