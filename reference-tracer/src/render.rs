//! Progressive rendering over all cores: one sample per pixel per pass, until a sample
//! count or a wall-clock budget is reached; guided methods learn during every pass and
//! rebuild their sampling distributions between passes.

use std::time::Instant;

use glam::Vec3;
use guiding_core::{EnvTileGuide, Guide, HemisphereGrid, Intersector, LightGuide, Pcg32};
use rayon::prelude::*;

use crate::integrator::{
    EnvironmentSampling, IntegratorSettings, LightSelection, PathCounters, PathScratch, PathTracer,
};
use crate::output::Image;
use crate::scene::Scene;
use crate::schedule::{Schedule, Step, Training};

/// When to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// After this many samples per pixel.
    SamplesPerPixel(u32),
    /// After the first pass that ends at or past this many seconds of rendering.
    Seconds(f64),
}

impl Budget {
    /// Whether a render that has done `passes` passes in `seconds` stops.
    pub fn reached(&self, passes: u32, seconds: f64) -> bool {
        match *self {
            Budget::SamplesPerPixel(spp) => passes >= spp,
            Budget::Seconds(limit) => seconds >= limit,
        }
    }
}

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
}

/// What the passes did.
#[derive(Clone, Debug, Default)]
pub struct RenderStatistics {
    /// Passes kept in the image (= samples per pixel).
    pub passes: u32,
    /// Training passes discarded before them.
    pub training_passes: u32,
    /// Seconds into the render when the last training pass ended.
    pub training_seconds: f64,
    /// Path counters of the training passes.
    pub training_counters: PathCounters,
    /// Path counters over all passes.
    pub counters: PathCounters,
    /// Wall-clock seconds from the first pass to the last.
    pub render_seconds: f64,
    /// Of which spent rebuilding guide distributions between passes.
    pub guide_rebuild_seconds: f64,
    /// Mean radiance (RGB) of each pass's image, for error estimates.
    pub pass_means: Vec<[f64; 3]>,
}

impl RenderStatistics {
    /// Paths per second of the passes kept in the image (after training).
    pub fn kept_paths_per_second(&self) -> f64 {
        let paths = self.counters.paths - self.training_counters.paths;
        paths as f64 / (self.render_seconds - self.training_seconds).max(1e-9)
    }

    /// Counts a finished pass whose samples summed to `pass_sum` over `pixels` pixels.
    pub fn add_pass(&mut self, pass_sum: [f64; 3], pixels: usize, counters: PathCounters) {
        self.pass_means.push(pass_sum.map(|s| s / pixels as f64));
        self.counters = self.counters + counters;
        self.passes += 1;
    }
}

/// The state after a pass, handed to the progress callback.
pub struct Progress<'a> {
    /// Passes done.
    pub passes: u32,
    /// Seconds since the first pass started.
    pub seconds: f64,
    /// Sum of all samples per pixel so far (divide by `passes` for the image).
    pub film: &'a [[f64; 3]],
    /// Counters so far.
    pub counters: PathCounters,
}

impl Progress<'_> {
    /// The current image estimate.
    pub fn image(&self, width: usize, height: usize) -> Image {
        let scale = 1.0 / self.passes.max(1) as f64;
        let pixels = self
            .film
            .iter()
            .map(|p| Vec3::new((p[0] * scale) as f32, (p[1] * scale) as f32, (p[2] * scale) as f32))
            .collect();
        Image { width, height, pixels }
    }
}

/// The learned structures a render uses; each is learned during every pass when the
/// settings ask for it. `G` is the directional guide's structure.
pub struct Learners<'a, G: Guide = HemisphereGrid> {
    /// The directional guide (guided methods).
    pub directions: Option<&'a mut G>,
    /// Learned light selection (`LightSelection::Learned`).
    pub lights: Option<&'a mut LightGuide>,
    /// Learned environment sampling (`EnvironmentSampling::Tiles`).
    pub environment: Option<&'a mut EnvTileGuide>,
}

impl<G: Guide> Default for Learners<'_, G> {
    fn default() -> Self {
        Self { directions: None, lights: None, environment: None }
    }
}

/// Renders `scene` progressively on the current rayon pool with `learners` (learned
/// during every pass); `on_pass` sees the state after every pass.
pub fn render<I: Intersector, G: Guide>(
    scene: &Scene,
    intersector: &I,
    learners: Learners<'_, G>,
    settings: &RenderSettings,
    mut on_pass: impl FnMut(&Progress<'_>),
) -> (Image, RenderStatistics) {
    let Learners { directions: mut guide, lights: mut light_guide, environment: mut environment_guide } = learners;
    let (width, height) = (scene.camera.width as usize, scene.camera.height as usize);
    let mut film = vec![[0.0f64; 3]; width * height];
    let mut statistics = RenderStatistics::default();
    let start = Instant::now();
    let guided = settings.integrator.method.uses_guide() && guide.is_some();
    let mut training = Training::new(guided && settings.schedule == Schedule::Iterative);
    // Passes traced so far, kept or not: each gets its own seed.
    let mut traced = 0u32;
    loop {
        let pass = traced;
        traced += 1;
        let integrator = IntegratorSettings {
            learn: settings.integrator.learn && (settings.schedule == Schedule::Online || training.learning()),
            ..settings.integrator
        };
        let tracer = PathTracer::new(
            scene,
            intersector,
            guide.as_deref(),
            light_guide.as_deref(),
            environment_guide.as_deref(),
            integrator,
        );
        let pass_seed = pass_seed(settings.seed, pass);
        // Rows come back in order, so the pass sum is added up in the same order on every
        // run: renders that do not learn are reproducible to the last bit.
        let rows: Vec<(PathCounters, [f64; 3])> = film
            .par_chunks_mut(width)
            .enumerate()
            .map_init(PathScratch::default, |scratch, (y, row)| {
                let mut counters = PathCounters::default();
                let mut row_sum = [0.0f64; 3];
                for (x, pixel) in row.iter_mut().enumerate() {
                    let mut rng = pixel_rng(pass_seed, (y * width + x) as u64);
                    let ray = tracer.camera_ray(x as u32, y as u32, &mut rng);
                    let radiance = tracer.radiance(ray, &mut rng, scratch, &mut counters);
                    // A NaN or infinite sample would poison the pixel for good: count the
                    // path as lost instead (it never happens with valid scenes).
                    let radiance = if radiance.is_finite() { radiance } else { Vec3::ZERO };
                    for c in 0..3 {
                        pixel[c] += radiance[c] as f64;
                        row_sum[c] += radiance[c] as f64;
                    }
                }
                (counters, row_sum)
            })
            .collect();
        let (counters, pass_sum) = rows.iter().fold((PathCounters::default(), [0.0f64; 3]), |(c, s), (rc, rs)| {
            (c + *rc, [s[0] + rs[0], s[1] + rs[1], s[2] + rs[2]])
        });
        statistics.add_pass(pass_sum, width * height, counters);
        let rebuild = Instant::now();
        let step = match settings.schedule {
            Schedule::Online => None,
            Schedule::Iterative => Some(training.after_pass(start.elapsed().as_secs_f64(), settings.budget)),
        };
        let refits = match step {
            None => true,
            Some(step) => matches!(step, Step::Refit { .. }),
        };
        if settings.integrator.method.uses_guide() && refits {
            if let Some(guide) = guide.as_deref_mut() {
                guide.rebuild_sampling();
            }
        }
        if settings.integrator.light_selection == LightSelection::Learned {
            if let Some(light_guide) = light_guide.as_deref_mut() {
                light_guide.rebuild();
            }
        }
        let learns_environment = settings.integrator.environment_sampling == EnvironmentSampling::Tiles;
        if learns_environment {
            if let Some(environment_guide) = environment_guide.as_deref_mut() {
                environment_guide.rebuild();
            }
        }
        statistics.guide_rebuild_seconds += rebuild.elapsed().as_secs_f64();
        let learns = settings.integrator.method.uses_guide()
            || settings.integrator.light_selection == LightSelection::Learned
            || learns_environment;
        let seconds = start.elapsed().as_secs_f64();
        let discarded = match step {
            Some(Step::Train | Step::Refit { .. }) => true,
            Some(Step::Render) | None => learns && seconds < settings.train_seconds,
        };
        if end_of_pass(&mut film, &mut statistics, settings, discarded, start, &mut on_pass) {
            break;
        }
    }
    (finished_image(&film, &statistics, width, height), statistics)
}

/// The bookkeeping after a pass has been added to `film` and `statistics`, shared by
/// the CPU and GPU render loops: a training pass (`discarded`) is taken out of the film
/// again; otherwise `on_pass` sees the state. Returns whether the budget is reached.
pub(crate) fn end_of_pass(
    film: &mut [[f64; 3]],
    statistics: &mut RenderStatistics,
    settings: &RenderSettings,
    discarded: bool,
    start: Instant,
    on_pass: &mut impl FnMut(&Progress<'_>),
) -> bool {
    let seconds = start.elapsed().as_secs_f64();
    if discarded {
        film.iter_mut().for_each(|p| *p = [0.0; 3]);
        statistics.pass_means.clear();
        statistics.passes = 0;
        statistics.training_passes += 1;
        statistics.training_seconds = seconds;
        statistics.training_counters = statistics.counters;
        return false;
    }
    on_pass(&Progress { passes: statistics.passes, seconds, film, counters: statistics.counters });
    if settings.budget.reached(statistics.passes, seconds) {
        statistics.render_seconds = seconds;
        return true;
    }
    false
}

/// The image of a finished progressive render: the film's mean over its passes.
pub(crate) fn finished_image(film: &[[f64; 3]], statistics: &RenderStatistics, width: usize, height: usize) -> Image {
    Progress { passes: statistics.passes, seconds: 0.0, film, counters: statistics.counters }.image(width, height)
}

/// SplitMix64's finaliser: a bijective mix in which every input bit affects every output bit.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The generator of one pixel in one pass. PCG streams that differ only in their
/// increment (one per pixel, from the same seed) give correlated sequences: a
/// furnace's guided-nee mean moved by 1 % (4 standard errors) when a path drew one
/// more number per vertex. Hashing the pixel into the seed and the stream avoids it.
fn pixel_rng(pass_seed: u64, pixel: u64) -> Pcg32 {
    let hashed = mix64(pixel.wrapping_add(0x9e37_79b9_7f4a_7c15));
    Pcg32::new(mix64(pass_seed ^ hashed), hashed)
}
