//! Progressive rendering over all cores: one sample per pixel per pass, until a sample
//! count or a wall-clock budget is reached; guided methods learn during every pass and
//! rebuild their sampling distributions between passes.

use std::time::Instant;

use glam::Vec3;
use guiding_core::{
    EfficiencyRoulette, EnvTileGuide, FocalGuide, Guide, HemisphereGrid, Intersector, LightGuide, NextEventGate,
    StrategyShares,
};
use rayon::prelude::*;

use crate::film::{Combine, Film};
use crate::image_estimates::ImageEstimates;
use crate::integrator::{EnvironmentSampling, IntegratorSettings, LightSelection, PathCounters, PathTracer, Roulette};
use crate::output::Image;
use crate::scene::Scene;
pub use crate::schedule::Budget;
use crate::schedule::{Schedule, Step, Training};

mod passes;

use passes::{camera_pass, splat_pass, vpl_pass, SplatGroup, WorkerRecords};

/// Training passes after which the iterative schedule may stop training where guiding
/// idles (the end of the iteration of 8 passes).
pub const IDLE_CHECK_PASSES: u32 = 15;

/// The seed of pass `pass` of a render seeded `seed`.
pub fn pass_seed(seed: u64, pass: u32) -> u64 {
    seed ^ (pass as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

/// Everything a render needs besides the scene, intersector and guide.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// The integrator.
    pub integrator: IntegratorSettings,
    /// When to stop.
    pub budget: Budget,
    /// Seed of every pixel's random numbers.
    pub seed: u64,
    /// Guided methods only: passes that end within this many seconds train the guide
    /// and are then discarded from the image. Their time counts towards a `Seconds`
    /// budget (so comparisons at equal time stay fair); a sample budget counts only the
    /// passes kept.
    pub train_seconds: f64,
    /// When guided methods learn: every pass, or in doubling training iterations
    /// followed by a frozen final image.
    pub schedule: Schedule,
    /// How the iterative schedule's iterations combine into the image.
    pub combine: Combine,
    /// The most of a seconds budget the iterative schedule trains for, in (0, 1]
    /// ([`DEFAULT_TRAINING_SHARE`](crate::schedule::DEFAULT_TRAINING_SHARE)).
    pub training_share: f64,
}

/// What the passes did.
#[derive(Clone, Debug, Default)]
pub struct RenderStatistics {
    /// Passes in the image (= samples per pixel).
    pub passes: u32,
    /// Passes that trained the guide (iterative schedule, or within `train_seconds`),
    /// whether the image kept them or not.
    pub training_passes: u32,
    /// Seconds into the render when the last training pass ended.
    pub training_seconds: f64,
    /// Whether training stopped early because guiding idled (see [`IDLE_CHECK_PASSES`]).
    pub training_stopped_idle: bool,
    /// Path counters of the training passes.
    pub training_counters: PathCounters,
    /// Path counters over all passes.
    pub counters: PathCounters,
    /// Wall-clock seconds from the first pass to the last.
    pub render_seconds: f64,
    /// Of which spent rebuilding guide distributions between passes.
    pub guide_rebuild_seconds: f64,
    /// Mean radiance (RGB) of each pass's image in the film, for error estimates.
    pub pass_means: Vec<[f64; 3]>,
    /// Learning records the GPU made past its record buffer's room, left unlearned (the
    /// tree guide on the GPU; 0 elsewhere).
    pub lost_records: u64,
}

impl RenderStatistics {
    /// Paths per second of the passes after training.
    pub fn kept_paths_per_second(&self) -> f64 {
        let paths = self.counters.paths - self.training_counters.paths;
        paths as f64 / (self.render_seconds - self.training_seconds).max(1e-9)
    }

    /// Counts a finished pass whose samples summed to `pass_sum` over `pixels` pixels.
    pub fn add_pass(&mut self, pass_sum: [f64; 3], pixels: usize, counters: PathCounters) {
        self.pass_means.push(pass_sum.map(|s| s / pixels as f64));
        self.counters = self.counters + counters;
    }
}

/// The state after a pass, handed to the progress callback.
pub struct Progress<'a> {
    /// Passes done.
    pub passes: u32,
    /// Seconds since the first pass started.
    pub seconds: f64,
    /// The samples so far.
    pub film: &'a Film,
    /// Counters so far.
    pub counters: PathCounters,
}

impl Progress<'_> {
    /// The current image estimate.
    pub fn image(&self) -> Image {
        self.film.image()
    }
}

/// The learned structures a render uses; each is learned during every pass when the
/// settings ask for it. `G` is the directional guide's structure.
pub struct Learners<'a, G: Guide = HemisphereGrid> {
    /// The directional guide (guided methods).
    pub directions: Option<&'a mut G>,
    /// W, the importance bdpt-guided's light subpaths learn and are guided by (a guide of
    /// the same structure as `directions`).
    pub importance: Option<&'a mut G>,
    /// The focal guide (guided methods with a focal probability above 0).
    pub focal: Option<&'a mut FocalGuide>,
    /// The directional guide's learned share per region (`learned_guide_share`).
    pub guide_shares: Option<&'a mut StrategyShares>,
    /// Learned light selection (`LightSelection::Learned`).
    pub lights: Option<&'a mut LightGuide>,
    /// The next-event gate (guided methods on the CPU); learns in learning passes.
    pub gate: Option<&'a mut NextEventGate>,
    /// Learned environment sampling (`EnvironmentSampling::Tiles`).
    pub environment: Option<&'a mut EnvTileGuide>,
    /// The efficiency-aware roulette's learned cells (`Roulette::Efficiency`).
    pub roulette: Option<&'a mut EfficiencyRoulette>,
}

impl<G: Guide> Learners<'_, G> {
    /// The learners `integrator` uses, every other one dropped: the one place that
    /// decides which learner a method uses, so that the render and the tracer take what
    /// they are given.
    /// - the directional guide and the focal guide (if its probability is above 0): guided
    ///   methods;
    /// - the learned shares: where the directional guide is and `learned_guide_share` is set;
    /// - W: where the directional guide is, for bdpt-guided's light subpaths (if
    ///   `guide_light_subpaths`) and vpl-guided's;
    /// - learned light selection, the next-event gate and the environment tiles: methods
    ///   that select lights as learned, estimate next-event light, and sample the
    ///   environment by tiles.
    pub fn used_by(self, integrator: &IntegratorSettings) -> Self {
        let method = integrator.method;
        let guided = method.uses_guide();
        let directions = self.directions.filter(|_| guided);
        let guides_light_paths =
            (method.bidirectional() && integrator.guide_light_subpaths) || method.gathers_virtual_lights();
        let with_directions = directions.is_some();
        Self {
            importance: self.importance.filter(|_| with_directions && guides_light_paths),
            focal: self.focal.filter(|_| guided && integrator.focal_probability > 0.0),
            guide_shares: self.guide_shares.filter(|_| with_directions && integrator.learned_guide_share),
            lights: self.lights.filter(|_| integrator.light_selection == LightSelection::Learned),
            gate: self.gate.filter(|_| method.uses_nee()),
            environment: self.environment.filter(|_| integrator.environment_sampling == EnvironmentSampling::Tiles),
            roulette: self.roulette.filter(|_| guided && integrator.roulette != Roulette::Throughput),
            directions,
        }
    }

    /// Whether any learner is there to learn.
    fn any(&self) -> bool {
        self.directions.is_some()
            || self.importance.is_some()
            || self.focal.is_some()
            || self.guide_shares.is_some()
            || self.lights.is_some()
            || self.gate.is_some()
            || self.environment.is_some()
            || self.roulette.is_some()
    }
}

impl<G: Guide> Default for Learners<'_, G> {
    fn default() -> Self {
        Self {
            directions: None,
            importance: None,
            focal: None,
            guide_shares: None,
            lights: None,
            gate: None,
            environment: None,
            roulette: None,
        }
    }
}

/// Renders `scene` progressively on the current rayon pool with the `learners` the
/// method uses ([`Learners::used_by`]; learned during every learning pass); `on_pass`
/// sees the state after every pass.
pub fn render<I: Intersector, G: Guide>(
    scene: &Scene,
    intersector: &I,
    learners: Learners<'_, G>,
    settings: &RenderSettings,
    mut on_pass: impl FnMut(&Progress<'_>),
) -> (Image, RenderStatistics) {
    let learners = learners.used_by(&settings.integrator);
    let learns = learners.any();
    let Learners {
        directions: mut guide,
        mut importance,
        mut focal,
        mut guide_shares,
        lights: mut light_guide,
        mut gate,
        environment: mut environment_guide,
        mut roulette,
    } = learners;
    let (width, height) = (scene.camera.width as usize, scene.camera.height as usize);
    let mut film = Film::new(width, height, settings.combine);
    let mut statistics = RenderStatistics::default();
    let start = Instant::now();
    let guided = guide.is_some() || focal.is_some();
    let mut training = Training::new(guided && settings.schedule == Schedule::Iterative, settings.training_share);
    // Passes traced so far, kept or not: each gets its own seed.
    let mut traced = 0u32;
    // Splat images and scratch space of light tracing and bdpt, one per group, kept
    // across passes.
    let mut splat_groups: Vec<SplatGroup<G::Region>> = Vec::new();
    // What the tracer derives from the scene, once; each pass adds its learners.
    let scene_tracer = PathTracer::<I, G>::new(scene, intersector, settings.integrator);
    // What the efficiency-aware roulette weighs paths against.
    let mut image_estimates = ImageEstimates::default();
    // The workers' records for the directional, light and environment guides, kept
    // across passes for their room.
    let mut worker_records: Vec<WorkerRecords<G::Records>> = Vec::new();
    loop {
        let pass = traced;
        traced += 1;
        let integrator = IntegratorSettings {
            learn: settings.integrator.learn && (settings.schedule == Schedule::Online || training.learning()),
            ..settings.integrator
        };
        let tracer = scene_tracer
            .clone()
            .with_settings(integrator)
            .with_guide(guide.as_deref())
            .with_focal_guide(focal.as_deref())
            .with_light_guide(light_guide.as_deref())
            .with_environment_guide(environment_guide.as_deref())
            .with_guide_shares(guide_shares.as_deref())
            .with_gate(gate.as_deref())
            .with_importance_guide(importance.as_deref())
            .with_roulette(roulette.as_deref(), image_estimates.relative_variance(), image_estimates.path_rays())
            .with_connection_threshold(connection_threshold(settings.integrator.connection_roulette, &statistics));
        let pass_seed = pass_seed(settings.seed, pass);
        let (counters, pass_sum) = if settings.integrator.method.splats() {
            splat_pass(&tracer, &mut film, &mut splat_groups, pass_seed)
        } else if settings.integrator.method.gathers_virtual_lights() {
            vpl_pass(&tracer, &mut film, pass_seed)
        } else {
            camera_pass(&tracer, &mut film, &image_estimates, pass_seed, &mut worker_records)
        };
        film.end_pass();
        statistics.add_pass(pass_sum, width * height, counters);
        image_estimates.count_pass(&counters);
        let rebuild = Instant::now();
        // The guide learns the pass's records before anything refits it (so none is stale).
        // The part of that which only reads the guide runs on every core first.
        if let Some(guide) = guide.as_deref() {
            worker_records.par_iter_mut().for_each(|records| guide.prepare_splat(&mut records.guide));
        }
        if let Some(guide) = guide.as_deref_mut() {
            for records in &mut worker_records {
                let left_out = guide.splat(&mut records.guide);
                debug_assert_eq!(left_out, 0, "records splatted after a refit");
            }
        }
        if let Some(light_guide) = light_guide.as_deref_mut() {
            for records in &mut worker_records {
                light_guide.splat(&mut records.nee.lights);
            }
        }
        if let Some(environment_guide) = environment_guide.as_deref_mut() {
            for records in &mut worker_records {
                environment_guide.splat(&mut records.nee.environment);
            }
        }
        let step = match settings.schedule {
            Schedule::Online => None,
            Schedule::Iterative => Some(training.after_pass(start.elapsed().as_secs_f64(), settings.budget)),
        };
        let refits = match step {
            None => true,
            Some(step) => matches!(step, Step::Refit { .. }),
        };
        if refits {
            if let Some(guide) = guide.as_deref_mut() {
                guide.rebuild_sampling();
            }
            if let Some(importance) = importance.as_deref_mut() {
                importance.rebuild_sampling();
            }
            if let Some(focal) = focal.as_deref_mut() {
                focal.rebuild_sampling();
            }
            if let Some(shares) = guide_shares.as_deref_mut() {
                shares.rebuild_sampling();
            }
            if let Some(roulette) = roulette.as_deref_mut() {
                roulette.rebuild_sampling();
                image_estimates.refit(&film);
            }
        }
        // Training stops early where guiding idles: once the shares learned from at least
        // IDLE_CHECK_PASSES passes leave the directional guide no cell and the focal guide
        // at most 1/16 of its cells, more training only costs time (many_lights: guided-nee
        // trained 255 passes, 8 s of 30, to use the guide nowhere and the boxes in 3 of 64
        // cells).
        if matches!(step, Some(Step::Refit { last: false })) && training.passes() >= IDLE_CHECK_PASSES {
            let guide_idle = guide_shares.as_deref().map(|shares| shares.cells_in_use() == 0);
            let focal_idle = focal.as_deref().is_none_or(|focal| {
                let (used, cells) = focal.selection_cells();
                used * 16 <= cells
            });
            if guide_idle == Some(true) && focal_idle {
                training.stop();
                statistics.training_stopped_idle = true;
            }
        }
        if let Some(light_guide) = light_guide.as_deref_mut() {
            light_guide.rebuild_sampling();
        }
        if let Some(gate) = gate.as_deref_mut() {
            // The gate counts only in learning passes: nothing to refit after others.
            if integrator.learn {
                gate.rebuild_sampling();
            }
        }
        if let Some(environment_guide) = environment_guide.as_deref_mut() {
            environment_guide.rebuild_sampling();
        }
        statistics.guide_rebuild_seconds += rebuild.elapsed().as_secs_f64();
        let seconds = start.elapsed().as_secs_f64();
        let keeps_training = settings.combine != Combine::Final;
        let fate = match step {
            Some(Step::Train) if keeps_training => PassFate::Train,
            Some(Step::Refit { .. }) if keeps_training => PassFate::EndsIteration,
            Some(Step::Train | Step::Refit { .. }) => PassFate::Discard,
            Some(Step::Render) | None if learns && seconds < settings.train_seconds => PassFate::Discard,
            Some(Step::Render) | None => PassFate::Keep,
        };
        if end_of_pass(&mut film, &mut statistics, settings, fate, start, &mut on_pass) {
            break;
        }
    }
    (film.image(), statistics)
}

/// bdpt's connection roulette threshold: `roulette` times the mean luminance of the
/// passes' images so far (0, every connection traced, when off or before the first).
fn connection_threshold(roulette: f32, statistics: &RenderStatistics) -> f32 {
    let pass_means = &statistics.pass_means;
    if roulette <= 0.0 || pass_means.is_empty() {
        return 0.0;
    }
    let sum = pass_means.iter().fold(Vec3::ZERO, |sum, m| sum + Vec3::new(m[0] as f32, m[1] as f32, m[2] as f32));
    roulette * crate::color::luminance(sum / pass_means.len() as f32)
}

/// What becomes of a finished pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PassFate {
    /// It is in the image.
    Keep,
    /// It trained the guide and stays in the current iteration of the image.
    Train,
    /// It trained the guide and ended an iteration, which joins the image by its weight.
    EndsIteration,
    /// It trained the guide and leaves the image, with the rest of its iteration.
    Discard,
}

/// The bookkeeping after a pass has been added to `film` (and counted by its `end_pass`)
/// and to `statistics`, shared by the CPU and GPU render loops: a pass that leaves the
/// image (`PassFate::Discard`) is taken out of the film again with the rest of its
/// iteration; otherwise `on_pass` sees the state. Returns whether the budget is reached.
pub(crate) fn end_of_pass(
    film: &mut Film,
    statistics: &mut RenderStatistics,
    settings: &RenderSettings,
    fate: PassFate,
    start: Instant,
    on_pass: &mut impl FnMut(&Progress<'_>),
) -> bool {
    let seconds = start.elapsed().as_secs_f64();
    if fate != PassFate::Keep {
        statistics.training_passes += 1;
        statistics.training_seconds = seconds;
        statistics.training_counters = statistics.counters;
    }
    match fate {
        PassFate::Discard => {
            film.discard_iteration();
            statistics.pass_means.truncate(film.passes() as usize);
            statistics.passes = film.passes();
            return false;
        }
        PassFate::EndsIteration => film.end_iteration(),
        PassFate::Keep | PassFate::Train => {}
    }
    // An iteration that counts for nothing (one pass, by inverse variance) left: its
    // passes were the last.
    statistics.pass_means.truncate(film.passes() as usize);
    statistics.passes = film.passes();
    on_pass(&Progress { passes: statistics.passes, seconds, film, counters: statistics.counters });
    if settings.budget.reached(statistics.passes, seconds) {
        statistics.render_seconds = seconds;
        return true;
    }
    false
}
