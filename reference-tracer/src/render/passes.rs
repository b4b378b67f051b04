//! One pass over the image on all cores: a camera path per pixel, instant radiosity's
//! gathering, or light paths and bidirectional samples splatted by groups; each pixel
//! draws from its own generator, so renders that do not learn are reproducible to the
//! last bit whatever the thread count.

use std::sync::Mutex;

use glam::Vec3;
use guiding_core::{Guide, Intersector, PathRecorder, Pcg32};
use rayon::prelude::*;

use crate::film::Film;
use crate::image_estimates::ImageEstimates;
use crate::integrator::{BidirectionalScratch, NeeRecords, PathCounters, PathScratch, PathTracer};

/// One camera path per pixel, added to `film`; the pass's counters and radiance sum.
/// `image_estimates` tells the efficiency-aware roulette what each pixel is expected to
/// be. The workers' records of the pass come back in `records` (whose buffers they took
/// up, so their room is reused), for [`Guide::splat`] and the light and environment
/// guides' splats.
pub(super) fn camera_pass<I: Intersector, G: Guide>(
    tracer: &PathTracer<'_, I, G>,
    film: &mut Film,
    image_estimates: &ImageEstimates,
    pass_seed: u64,
    records: &mut Vec<WorkerRecords<G::Records>>,
) -> (PathCounters, [f64; 3]) {
    let width = film.width();
    let pool = Mutex::new(std::mem::take(records));
    let scratch = || {
        let mut scratch = PathScratch::default();
        let taken = pool.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).pop().unwrap_or_default();
        (scratch.records, scratch.nee_records) = (taken.guide, taken.nee);
        ReturningScratch { scratch, pool: &pool }
    };
    let pass = if tracer.traces_in_lanes() {
        // Rows enough that a task's lanes are full for all but a sliver of its paths: a
        // lane whose path ends takes the next pixel, and only the task's last paths run
        // with lanes empty beside them.
        let lanes = tracer.settings().lanes as usize;
        let rows = (lanes * PIXELS_PER_LANE).div_ceil(width.max(1)).max(1);
        row_pass(film, rows, scratch, |worker, y, pixels, counters| {
            let first = y as usize * width;
            let rng_of = |i: usize| pixel_rng(pass_seed, (first + i) as u64);
            let pixel_of = |i: usize| (((first + i) % width) as u32, ((first + i) / width) as u32);
            let PathScratch { lanes, nee_records, .. } = &mut worker.scratch;
            tracer.radiance_in_lanes(pixels, pixel_of, rng_of, lanes, nee_records, counters);
        })
    } else {
        pixel_pass(film, pass_seed, scratch, |worker, (x, y), rng, counters| {
            let ray = tracer.camera_ray(x, y, rng);
            let estimate = image_estimates.pixel(y as usize * width + x as usize);
            tracer.radiance(ray, estimate, rng, &mut worker.scratch, counters)
        })
    };
    *records = pool.into_inner().unwrap_or_else(|poisoned| poisoned.into_inner());
    pass
}

/// A worker's records of a pass: the directional guide's and next-event estimation's.
#[derive(Default)]
pub(super) struct WorkerRecords<B> {
    /// For [`Guide::splat`].
    pub(super) guide: B,
    /// For the light and environment guides' splats.
    pub(super) nee: NeeRecords,
}

/// A worker's scratch space, whose records go back to the pass's `pool` when the worker
/// is done with it.
struct ReturningScratch<'a, R, B: Default> {
    scratch: PathScratch<R, B>,
    pool: &'a Mutex<Vec<WorkerRecords<B>>>,
}

impl<R, B: Default> Drop for ReturningScratch<'_, R, B> {
    fn drop(&mut self) {
        let guide = std::mem::take(&mut self.scratch.records);
        let nee = std::mem::take(&mut self.scratch.nee_records);
        self.pool.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).push(WorkerRecords { guide, nee });
    }
}

/// Instant radiosity: the pass's virtual point lights from `vpl_paths` light subpaths
/// (their random numbers from the pass seed alone, so the same seed gives the same
/// lights in every frame of an animation), then one gathering camera ray per pixel; in
/// vpl-guided's learning passes W then learns what each light gave the image.
pub(super) fn vpl_pass<I: Intersector, G: Guide>(
    tracer: &PathTracer<'_, I, G>,
    film: &mut Film,
    pass_seed: u64,
) -> (PathCounters, [f64; 3]) {
    let settings = tracer.settings();
    let mut light_rng = pixel_rng(pass_seed, u64::MAX);
    let mut light_counters = PathCounters::default();
    let vpls = tracer.virtual_point_lights(settings.vpl_paths, &mut light_rng, &mut light_counters);
    let min_distance = settings.vpl_min_distance * tracer.scene_extent();
    let learning = settings.learn && tracer.importance_guide().is_some();
    // The tallies exist only where W learns: other passes gather without them.
    let total = std::sync::Mutex::new(if learning { vpls.tally() } else { Vec::new() });
    let tally = || Tally { local: learning.then(|| vpls.tally()), total: &total };
    let (counters, pass_sum) = pixel_pass(film, pass_seed, tally, |tally, (x, y), rng, counters| {
        let ray = tracer.camera_ray(x, y, rng);
        tracer.gather(ray, &vpls, min_distance, rng, counters, tally.local.as_deref_mut())
    });
    if learning {
        let total = total.into_inner().unwrap_or_else(|poisoned| poisoned.into_inner());
        tracer.teach_virtual_lights(&vpls, &total, film.pixels_mut().len(), &mut PathRecorder::new());
    }
    (counters + light_counters, pass_sum)
}

/// A worker's sums of what each virtual light gave its pixels, added into the pass's
/// `total` when the worker is done with it.
struct Tally<'a> {
    local: Option<Vec<f32>>,
    total: &'a std::sync::Mutex<Vec<f32>>,
}

impl Drop for Tally<'_> {
    fn drop(&mut self) {
        let Some(local) = &self.local else { return };
        let mut total = self.total.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        for (sum, value) in total.iter_mut().zip(local) {
            *sum += value;
        }
    }
}

/// One sample per pixel from `sample` (given per-thread scratch made by `scratch`, the
/// pixel, its generator and counters), added to `film`; the pass's counters and
/// radiance sum.
fn pixel_pass<S>(
    film: &mut Film,
    pass_seed: u64,
    scratch: impl Fn() -> S + Sync + Send,
    sample: impl Fn(&mut S, (u32, u32), &mut Pcg32, &mut PathCounters) -> Vec3 + Sync + Send,
) -> (PathCounters, [f64; 3]) {
    let width = film.width();
    row_pass(film, 1, scratch, |scratch, y, row, counters| {
        for (x, radiance) in row.iter_mut().enumerate() {
            let mut rng = pixel_rng(pass_seed, (y as usize * width + x) as u64);
            *radiance = sample(scratch, (x as u32, y), &mut rng, counters);
        }
    })
}

/// Pixels a task of the lane loop holds per lane, at least.
const PIXELS_PER_LANE: usize = 32;

/// One sample per pixel, `rows` rows at a time from `sample_rows` (given per-thread
/// scratch made by `scratch`, the first row's y, the samples of its rows to fill, row
/// after row, and counters), added to `film`; the pass's counters and radiance sum.
/// Rows are summed one by one and come back in order, so the pass sum is added up in
/// the same order on every run, whatever `rows`: renders that do not learn are
/// reproducible to the last bit.
fn row_pass<S>(
    film: &mut Film,
    rows: usize,
    scratch: impl Fn() -> S + Sync + Send,
    sample_rows: impl Fn(&mut S, u32, &mut [Vec3], &mut PathCounters) + Sync + Send,
) -> (PathCounters, [f64; 3]) {
    let width = film.width();
    let rows = rows.max(1);
    let tasks: Vec<(PathCounters, Vec<[f64; 3]>)> = film
        .pixels_mut()
        .par_chunks_mut(width * rows)
        .enumerate()
        .map_init(
            || (scratch(), Vec::new()),
            |(scratch, samples), (task, pixels)| {
                let mut counters = PathCounters::default();
                samples.clear();
                samples.resize(pixels.len(), Vec3::ZERO);
                sample_rows(scratch, (task * rows) as u32, samples, &mut counters);
                let row_sums = pixels
                    .chunks_mut(width)
                    .zip(samples.chunks(width))
                    .map(|(pixels, samples)| {
                        let mut row_sum = [0.0f64; 3];
                        for (pixel, &radiance) in pixels.iter_mut().zip(samples) {
                            // A NaN or infinite sample would poison the pixel for good:
                            // count the path as lost instead (it never happens with valid
                            // scenes).
                            let radiance = if radiance.is_finite() { radiance } else { Vec3::ZERO };
                            Film::add(pixel, radiance);
                            for c in 0..3 {
                                row_sum[c] += radiance[c] as f64;
                            }
                        }
                        row_sum
                    })
                    .collect();
                (counters, row_sums)
            },
        )
        .collect();
    tasks.iter().fold((PathCounters::default(), [0.0f64; 3]), |(c, mut s), (tc, row_sums)| {
        for rs in row_sums {
            s = [s[0] + rs[0], s[1] + rs[1], s[2] + rs[2]];
        }
        (c + *tc, s)
    })
}

/// Groups of light paths (or bidirectional samples) traced in parallel, each group into
/// its own splat image; the images are summed in a fixed order, so such a render is
/// reproducible to the last bit whatever the thread count (which this also caps).
const SPLAT_GROUPS: usize = 8;

/// One group's splat image (a value per pixel, row by row) and the scratch space its
/// paths reuse: the recorder light paths learn through, the bidirectional subpaths.
pub(super) struct SplatGroup<R> {
    splat: Vec<Vec3>,
    recorder: PathRecorder<R>,
    subpaths: BidirectionalScratch<R>,
}

/// As many light paths (or bidirectional samples, one per pixel) as pixels, each adding
/// to its group's splat image; the summed image is added to `film` as one sample per
/// pixel (a pixel's value is its splats times the pixel count over the light paths
/// traced: one here). `groups` holds the groups' buffers from pass to pass (made on the
/// first).
pub(super) fn splat_pass<I: Intersector, G: Guide>(
    tracer: &PathTracer<'_, I, G>,
    film: &mut Film,
    groups: &mut Vec<SplatGroup<G::Region>>,
    pass_seed: u64,
) -> (PathCounters, [f64; 3]) {
    let pixels = film.pixels_mut().len();
    let width = film.width();
    let per_group = pixels.div_ceil(SPLAT_GROUPS);
    let bidirectional = tracer.settings().method.bidirectional();
    groups.resize_with(SPLAT_GROUPS, || SplatGroup {
        splat: vec![Vec3::ZERO; pixels],
        recorder: PathRecorder::new(),
        subpaths: BidirectionalScratch::default(),
    });
    let counters: Vec<PathCounters> = groups
        .par_iter_mut()
        .enumerate()
        .map(|(group, SplatGroup { splat, recorder, subpaths })| {
            splat.fill(Vec3::ZERO);
            let mut counters = PathCounters::default();
            for path in group * per_group..((group + 1) * per_group).min(pixels) {
                let mut rng = pixel_rng(pass_seed, path as u64);
                if bidirectional {
                    let pixel = ((path % width) as u32, (path / width) as u32);
                    tracer.bidirectional_sample(pixel, &mut rng, splat, subpaths, &mut counters);
                } else {
                    tracer.light_path(&mut rng, splat, recorder, &mut counters);
                }
            }
            counters
        })
        .collect();
    let counters = counters.into_iter().fold(PathCounters::default(), |sum, c| sum + c);
    let mut pass_sum = [0.0f64; 3];
    for (index, pixel) in film.pixels_mut().iter_mut().enumerate() {
        let value = groups.iter().fold(Vec3::ZERO, |sum, group| sum + group.splat[index]);
        let value = if value.is_finite() { value } else { Vec3::ZERO };
        Film::add(pixel, value);
        for c in 0..3 {
            pass_sum[c] += value[c] as f64;
        }
    }
    (counters, pass_sum)
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
