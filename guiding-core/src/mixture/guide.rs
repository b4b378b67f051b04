//! [`GaussianMixture`]: Q per region of a grid as a von Mises–Fisher mixture, learned by
//! stepwise EM from the tracer's (direction, target, pdf) stream.

use alloc::vec::Vec;
use core::f32::consts::PI;
use core::mem::size_of;
use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

use glam::{Vec2, Vec3};

use crate::atomic_f32;
use crate::cell_grid::CellGrid;
use crate::distribution::{fold_onto_hemisphere, folded_pdf, DirectionSample, DirectionalDistribution, UniformSphere};
use crate::error::Error;
use crate::guide::{Guide, GuideStats};
use crate::scattering::ScatteringFunction;
use crate::update_rule::{accept_target, LearningRate, UpdateOutcome};

use super::settings::{batch_stride, GaussianMixtureSettings};
use super::vmf::{MAX_CONCENTRATION, MIN_CONCENTRATION};
use super::vmf_mixture::{VmfMixture, MAX_LOBES};

/// Largest sample weight target/pdf a batch takes: sums of many stay finite in f32.
const MAX_SAMPLE_WEIGHT: f64 = 1e30;

/// A region of a [`GaussianMixture`] at one surface point: the mixture it samples (a
/// grid cell, or one normal-direction sixth of it) and the normal its hemisphere folds
/// onto.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixtureRegion {
    /// Index of the region's mixture, in `0..region_count()`.
    pub index: u32,
    /// Unit normal of the surface: sampling folds the sphere onto its side.
    pub normal: Vec3,
}

/// Q(x, ω) ≈ S(x)·p(ω | x): per region of a grid over the scene, a vMF mixture p (up to
/// 8 lobes) over the whole sphere and the scale S = ∫Q dω (radiance × steradian).
/// Sampling at a surface folds the sphere onto the normal's hemisphere, as the volume
/// does: a direction below the surface would find f = 0 and end the path.
///
/// Each update computes the sample's responsibilities under the region's current
/// mixture and adds r_k·v and r_k·v·ω (v = target/pdf) to the region's batch sums, with
/// lock-free float adds. [`rebuild_sampling`](Guide::rebuild_sampling) then blends each
/// batch's averages into the region's running statistics by the update rule's step —
/// simple averaging (step n/(N+n), every sample alike), a constant α per sample (step
/// 1 − (1−α)ⁿ) or the global schedule — and refits (the M-step). So a pass samples one
/// fixed mixture exactly, and what it learns takes effect at the next.
///
/// ```
/// use guiding_core::mixture::{GaussianMixture, GaussianMixtureSettings};
/// use guiding_core::{Guide, DirectionalDistribution, Pcg32};
/// use glam::Vec3;
/// let mut guide = GaussianMixture::new(Vec3::ZERO, Vec3::ONE, GaussianMixtureSettings::default()).unwrap();
/// let region = guide.locate(Vec3::splat(0.5), Vec3::Y).unwrap();
/// let mut rng = Pcg32::new(1, 1);
/// for _ in 0..4 {
///     for _ in 0..5000 {
///         let s = guide.sample(region, rng.next_vec2());
///         let light = 10.0 * s.direction.x.max(0.0).powi(8);
///         guide.update_sampled(region, s.direction, light, s.pdf);
///     }
///     guide.rebuild_sampling();
/// }
/// assert!(guide.pdf(region, Vec3::X) > 10.0 * guide.pdf(region, -Vec3::X));
/// ```
pub struct GaussianMixture {
    pub(crate) settings: GaussianMixtureSettings,
    pub(crate) low: Vec3,
    pub(crate) high: Vec3,
    pub(crate) grid: CellGrid,
    /// Each region's mixture: the sampling snapshot plus its running statistics.
    pub(crate) mixtures: Vec<VmfMixture>,
    /// Per region [`batch_stride`] words: sample count (u32), then per lobe Σ r·v and
    /// Σ r·v·ω (f32 bits).
    pub(crate) batch: Vec<AtomicU32>,
    pub(crate) epoch: u32,
    pub(crate) rejected_non_finite: AtomicUsize,
    pub(crate) rejected_negative: AtomicUsize,
}

/// The sampling distribution of one region: the mixture, with a share spread uniformly,
/// folded onto the normal's hemisphere.
#[derive(Clone, Copy, Debug)]
pub struct MixtureDistribution<'a> {
    mixture: &'a VmfMixture,
    uniform_mix: f32,
    normal: Vec3,
}

impl MixtureDistribution<'_> {
    /// The density over the whole sphere, before folding.
    fn sphere_pdf(&self, direction: Vec3) -> f32 {
        (1.0 - self.uniform_mix) * self.mixture.pdf(direction) + self.uniform_mix * (0.25 / PI)
    }
}

impl DirectionalDistribution for MixtureDistribution<'_> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let direction = if u.x < self.uniform_mix {
            UniformSphere.sample(Vec2::new(u.x / self.uniform_mix, u.y)).direction
        } else {
            let rescaled = ((u.x - self.uniform_mix) / (1.0 - self.uniform_mix)).min(1.0 - f32::EPSILON / 2.0);
            self.mixture.sample(Vec2::new(rescaled, u.y)).direction
        };
        let direction = fold_onto_hemisphere(direction, self.normal);
        DirectionSample { direction, pdf: self.pdf(direction) }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        folded_pdf(direction, self.normal, |d| self.sphere_pdf(d))
    }
}

impl GaussianMixture {
    /// A guide over the box `low..high` (scene units; points outside use the nearest
    /// cell), every region starting uniform with ∫Q dω = 4π·initial_q.
    pub fn new(low: Vec3, high: Vec3, settings: GaussianMixtureSettings) -> Result<Self, Error> {
        let grid = Self::grid_for(low, high, &settings)?;
        let regions = grid.cell_count() * settings.regions_per_cell();
        let mixtures = (0..regions).map(|_| initial_mixture(&settings)).collect();
        let batch = (0..regions * batch_stride(settings.lobes)).map(|_| AtomicU32::new(0)).collect();
        Ok(Self {
            settings,
            low,
            high,
            grid,
            mixtures,
            batch,
            epoch: 0,
            rejected_non_finite: AtomicUsize::new(0),
            rejected_negative: AtomicUsize::new(0),
        })
    }

    /// The grid `new` lays over `low..high` (checks the settings; allocates nothing).
    pub(crate) fn grid_for(low: Vec3, high: Vec3, settings: &GaussianMixtureSettings) -> Result<CellGrid, Error> {
        settings.validate()?;
        let per_cell = settings.regions_per_cell() * settings.bytes_per_region();
        CellGrid::new(low, high, settings.resolution, settings.budget_bytes, per_cell)
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &GaussianMixtureSettings {
        &self.settings
    }

    /// The box the grid covers.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.low, self.high)
    }

    /// Cells along x, y and z.
    pub fn resolution(&self) -> [u32; 3] {
        self.grid.resolution()
    }

    /// Number of regions (cells × regions per cell).
    pub fn region_count(&self) -> usize {
        self.mixtures.len()
    }

    /// The mixture of region `index` (the sampling snapshot and its statistics).
    pub fn mixture(&self, index: usize) -> &VmfMixture {
        &self.mixtures[index]
    }

    /// Replaces the mixture of region `index` (e.g. a prior, or a test's table) and
    /// drops its pending batch.
    pub fn set_mixture(&mut self, index: usize, mixture: VmfMixture) {
        self.mixtures[index] = mixture;
        let stride = batch_stride(self.settings.lobes);
        self.batch[index * stride..(index + 1) * stride].iter().for_each(|w| w.store(0, Ordering::Relaxed));
    }

    /// Every region's sampling snapshot as a flat table for a tracer elsewhere (a GPU):
    /// per region, per lobe ([`lobes`](GaussianMixtureSettings::lobes) of them), 8 f32:
    /// the unit mean (x, y, z), κ, the normalization C(κ) (per steradian), the lobe's
    /// weight, the region's total weight S (radiance × sr, repeated in every lobe), and
    /// the index of the region's broadest lobe (which takes a direction no lobe claims).
    pub fn lobe_table(&self) -> Vec<f32> {
        let lobes = self.settings.lobes;
        let mut table = Vec::with_capacity(self.mixtures.len() * lobes * 8);
        for mixture in &self.mixtures {
            let broadest = (0..mixture.lobe_count())
                .min_by(|&a, &b| mixture.lobe(a).0.concentration().total_cmp(&mixture.lobe(b).0.concentration()))
                .unwrap_or(0);
            let scale = mixture.total_weight();
            for k in 0..lobes {
                let (lobe, weight) = if k < mixture.lobe_count() { mixture.lobe(k) } else { (mixture.lobe(0).0, 0.0) };
                let mean = lobe.mean();
                table.extend_from_slice(&[
                    mean.x,
                    mean.y,
                    mean.z,
                    lobe.concentration(),
                    lobe.normalization(),
                    weight,
                    scale,
                    broadest as f32,
                ]);
            }
        }
        table
    }

    /// The pending batch sums, region after region: per region the sample count (u32),
    /// then per lobe Σ r·v and Σ r·v·ω's x, y, z (f32 bits), v = target / sampling pdf.
    /// A tracer that learns elsewhere adds into a copy and stores it back here before
    /// [`rebuild_sampling`](Guide::rebuild_sampling) takes the M-step.
    pub fn batch_words(&self) -> &[AtomicU32] {
        &self.batch
    }

    /// The grid's low corner and its cells per unit length along each axis: a point's
    /// cell coordinates are `(position - low) * inverse_cell_size`, clamped to the grid;
    /// its region is cell × regions per cell + normal side (see
    /// [`locate`](Guide::locate)).
    pub fn grid_transform(&self) -> (Vec3, Vec3) {
        self.grid.transform()
    }

    /// Bytes held by the mixtures and the batch sums.
    pub fn memory_bytes(&self) -> usize {
        self.mixtures.len() * size_of::<VmfMixture>() + self.batch.len() * size_of::<AtomicU32>()
    }

    /// Grid epoch, rejected counts and the raw tables, for serialization.
    pub(crate) fn raw_state(&self) -> (u32, usize, usize, &[VmfMixture], &[AtomicU32]) {
        (
            self.epoch,
            self.rejected_non_finite.load(Ordering::Relaxed),
            self.rejected_negative.load(Ordering::Relaxed),
            &self.mixtures,
            &self.batch,
        )
    }

    /// A guide from decoded parts; the caller checked the shapes match `settings`.
    pub(crate) fn assemble(
        mut guide: Self,
        epoch: u32,
        rejected: (usize, usize),
        mixtures: Vec<VmfMixture>,
        batch: Vec<u32>,
    ) -> Self {
        guide.epoch = epoch;
        guide.rejected_non_finite = AtomicUsize::new(rejected.0);
        guide.rejected_negative = AtomicUsize::new(rejected.1);
        guide.mixtures = mixtures;
        guide.batch = batch.into_iter().map(AtomicU32::new).collect();
        guide
    }

    pub(crate) fn batch_row(&self, region: usize) -> &[AtomicU32] {
        let stride = batch_stride(self.settings.lobes);
        &self.batch[region * stride..(region + 1) * stride]
    }

    /// The step by which a batch of `count` samples moves statistics that have seen
    /// `seen` samples before.
    fn batch_step(&self, count: u32, seen: u32) -> f32 {
        match self.settings.update_rule.learning_rate {
            LearningRate::SimpleAverage | LearningRate::RegionVisits => {
                (count as f64 / (seen as f64 + count as f64)) as f32
            }
            LearningRate::Exponential { alpha } => (1.0 - libm::pow(1.0 - alpha as f64, count as f64)) as f32,
            LearningRate::Global { exponent } => libm::pow(1.0 + self.epoch as f64, -(exponent as f64)) as f32,
        }
    }
}

/// A uniform mixture whose statistics say ∫Q dω = 4π·initial_q.
fn initial_mixture(settings: &GaussianMixtureSettings) -> VmfMixture {
    let uniform = VmfMixture::uniform(settings.lobes);
    let lobes: [_; MAX_LOBES] = core::array::from_fn(|k| uniform.lobe(k.min(settings.lobes - 1)));
    VmfMixture::from_lobes(&lobes[..settings.lobes], 4.0 * PI * settings.initial_q)
}

/// Adds `value` to the f32 in `word`, saturating at ±f32::MAX.
fn add_to(word: &AtomicU32, value: f32) {
    if value != 0.0 {
        atomic_f32::update(word, |sum| (sum as f64 + value as f64).clamp(-(f32::MAX as f64), f32::MAX as f64) as f32);
    }
}

impl Clone for GaussianMixture {
    /// A copy of the mixtures, the pending batch and the counters (the atomics read once).
    fn clone(&self) -> Self {
        let copy = |count: &AtomicUsize| AtomicUsize::new(count.load(Ordering::Relaxed));
        Self {
            settings: self.settings,
            low: self.low,
            high: self.high,
            grid: self.grid,
            mixtures: self.mixtures.clone(),
            batch: self.batch.iter().map(|word| AtomicU32::new(word.load(Ordering::Relaxed))).collect(),
            epoch: self.epoch,
            rejected_non_finite: copy(&self.rejected_non_finite),
            rejected_negative: copy(&self.rejected_negative),
        }
    }
}

impl Guide for GaussianMixture {
    type Records = ();
    type Region = MixtureRegion;
    type Distribution<'a> = MixtureDistribution<'a>;

    fn locate(&self, position: Vec3, normal: Vec3) -> Option<MixtureRegion> {
        let normal = normal.try_normalize()?;
        let cell = self.grid.cell(position)?;
        let side = if self.settings.split_by_normal {
            let a = normal.abs();
            let axis = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            2 * axis as u32 + (normal[axis] < 0.0) as u32
        } else {
            0
        };
        Some(MixtureRegion { index: cell * self.settings.regions_per_cell() as u32 + side, normal })
    }

    fn distribution(&self, region: MixtureRegion) -> MixtureDistribution<'_> {
        MixtureDistribution {
            mixture: &self.mixtures[region.index as usize],
            uniform_mix: self.settings.uniform_mix,
            normal: region.normal,
        }
    }

    /// Takes the direction as drawn uniformly over the sphere (pdf 1/4π).
    fn update(&self, region: MixtureRegion, direction: Vec3, target: f32) -> UpdateOutcome {
        self.update_sampled(region, direction, target, 0.25 / PI)
    }

    fn update_sampled(&self, region: MixtureRegion, direction: Vec3, target: f32, pdf: f32) -> UpdateOutcome {
        let target = match accept_target(target, &self.rejected_negative, &self.rejected_non_finite) {
            Ok(t) => t,
            Err(rejected) => return rejected,
        };
        let unit = direction.is_finite() && (direction.length_squared() - 1.0).abs() < 1e-3;
        if !(unit && pdf.is_finite() && pdf > 0.0) {
            return UpdateOutcome::OutsideDomain;
        }
        let weight = (target as f64 / pdf as f64).min(MAX_SAMPLE_WEIGHT) as f32;
        let index = region.index as usize;
        let responsibility = self.mixtures[index].responsibilities(direction);
        let row = self.batch_row(index);
        atomic_f32::increment_saturating(&row[0]);
        for (k, words) in row[1..].chunks_exact(4).enumerate() {
            let share = responsibility[k] * weight;
            add_to(&words[0], share);
            add_to(&words[1], share * direction.x);
            add_to(&words[2], share * direction.y);
            add_to(&words[3], share * direction.z);
        }
        UpdateOutcome::Accepted
    }

    /// S·Σ_k w_k·fs(ω_k)·cos θ_k with ω_k drawn from lobe k by `u`: one sample per lobe,
    /// unbiased for ∫ S·p(ω) fs cos dω whatever the integral estimator setting.
    fn estimate_integral<S: ScatteringFunction + ?Sized>(
        &self,
        region: MixtureRegion,
        wo: Vec3,
        bsdf: &S,
        u: Vec2,
    ) -> f32 {
        let mixture = &self.mixtures[region.index as usize];
        let scale = mixture.total_weight();
        if scale <= 0.0 {
            return 0.0;
        }
        let sum: f64 = (0..mixture.lobe_count())
            .map(|k| {
                let (lobe, weight) = mixture.lobe(k);
                weight as f64 * bsdf.eval_cos(lobe.sample(u), wo) as f64
            })
            .sum();
        (scale as f64 * sum).min(f32::MAX as f64) as f32
    }

    fn update_rule(&self) -> crate::update_rule::UpdateRule {
        self.settings.update_rule
    }

    fn rebuild_sampling(&mut self) {
        let lobes = self.settings.lobes;
        for index in 0..self.mixtures.len() {
            let row = self.batch_row(index);
            let count = row[0].load(Ordering::Relaxed);
            if count == 0 {
                continue;
            }
            let mean = |word: &AtomicU32| (atomic_f32::load(word) as f64 / count as f64) as f32;
            let mut s0 = [0.0f32; MAX_LOBES];
            let mut s1 = [Vec3::ZERO; MAX_LOBES];
            for (k, words) in row[1..].chunks_exact(4).enumerate().take(lobes) {
                s0[k] = mean(&words[0]);
                s1[k] = Vec3::new(mean(&words[1]), mean(&words[2]), mean(&words[3]));
            }
            row.iter().for_each(|w| w.store(0, Ordering::Relaxed));
            let step = self.batch_step(count, self.mixtures[index].observations());
            let mixture = &mut self.mixtures[index];
            if step > 0.0 {
                mixture.absorb(&s0, &s1, step.min(1.0));
                mixture.refit();
            }
            mixture.add_observations(count);
        }
        self.epoch = self.epoch.saturating_add(1);
    }

    /// `visited_entries` counts the lobes of regions that took at least one sample.
    fn stats(&self) -> GuideStats {
        let stride = batch_stride(self.settings.lobes);
        let (mut accepted, mut visited) = (0u64, 0usize);
        for (mixture, row) in self.mixtures.iter().zip(self.batch.chunks_exact(stride)) {
            let samples = mixture.observations() as u64 + row[0].load(Ordering::Relaxed) as u64;
            accepted += samples;
            visited += (samples > 0) as usize * mixture.lobe_count();
        }
        GuideStats {
            regions: self.mixtures.len(),
            entries_per_region: self.settings.lobes,
            memory_bytes: self.memory_bytes(),
            accepted_updates: accepted,
            visited_entries: visited,
            rejected_non_finite: self.rejected_non_finite.load(Ordering::Relaxed) as u64,
            rejected_negative: self.rejected_negative.load(Ordering::Relaxed) as u64,
            epochs: self.epoch,
        }
    }

    fn validate(&self) -> Result<(), Error> {
        for (index, mixture) in self.mixtures.iter().enumerate() {
            check_mixture(mixture, index, self.settings.lobes)?;
        }
        let stride = batch_stride(self.settings.lobes);
        for (index, word) in self.batch.iter().enumerate() {
            if index % stride != 0 && !atomic_f32::load(word).is_finite() {
                return Err(crate::bytes::invalid_field("batch", index, "finite sums"));
            }
        }
        Ok(())
    }

    fn to_bytes(&self) -> Vec<u8> {
        super::serialize::encode(self)
    }

    fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        super::serialize::decode(bytes)
    }

    fn merge(&mut self, other: &Self) -> Result<(), Error> {
        GaussianMixture::merge(self, other)
    }
}

/// Checks one mixture: `lobes` lobes with unit means and concentrations in range,
/// weights ≥ 0 summing to 1, finite statistics with S0 ≥ 0.
pub(crate) fn check_mixture(mixture: &VmfMixture, index: usize, lobes: usize) -> Result<(), Error> {
    let invalid = |field, requirement| Err(crate::bytes::invalid_field(field, index, requirement));
    if mixture.lobe_count() != lobes {
        return invalid("lobes", "the settings' lobe count");
    }
    let (means, weights, s0, s1, _) = mixture.parts();
    for lobe in means {
        let kappa = lobe.concentration();
        if !(lobe.mean().is_finite() && (lobe.mean().length() - 1.0).abs() < 1e-4) {
            return invalid("lobe_means", "finite and unit length");
        }
        if !(kappa == 0.0 || (MIN_CONCENTRATION..=MAX_CONCENTRATION).contains(&kappa)) {
            return invalid("lobe_concentrations", "0 or in [1e-4, 1e4]");
        }
    }
    let sum: f32 = weights.iter().sum();
    if !(weights.iter().all(|w| w.is_finite() && *w >= 0.0) && (sum - 1.0).abs() < 1e-3) {
        return invalid("lobe_weights", "finite, ≥ 0 and summing to 1");
    }
    if !(s0.iter().all(|s| s.is_finite() && *s >= 0.0) && s1.iter().all(|s| s.is_finite())) {
        return invalid("statistics", "finite, with Σ r·v ≥ 0");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;
    use crate::update_rule::UpdateRule;

    fn guide(rule: LearningRate) -> GaussianMixture {
        let settings = GaussianMixtureSettings {
            resolution: Some([2, 2, 2]),
            update_rule: UpdateRule { learning_rate: rule, ..Default::default() },
            ..Default::default()
        };
        GaussianMixture::new(Vec3::ZERO, Vec3::ONE, settings).unwrap()
    }

    /// One batch of samples from the region's own distribution, lit from around +x.
    fn teach(guide: &GaussianMixture, region: MixtureRegion, samples: u32, seed: u64) {
        let mut rng = Pcg32::new(seed, 3);
        for _ in 0..samples {
            let s = guide.sample(region, rng.next_vec2());
            let light = 5.0 * s.direction.x.max(0.0).powi(4);
            assert_eq!(guide.update_sampled(region, s.direction, light, s.pdf), UpdateOutcome::Accepted);
        }
    }

    #[test]
    fn regions_follow_cells_and_normal_sides() {
        let guide = guide(LearningRate::SimpleAverage);
        assert_eq!(guide.region_count(), 8 * 6);
        let p = Vec3::splat(0.25);
        let sides: Vec<_> = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
            .iter()
            .map(|&n| guide.locate(p, n).unwrap().index)
            .collect();
        assert_eq!(sides, [0, 1, 2, 3, 4, 5]);
        assert_eq!(guide.locate(Vec3::splat(0.75), Vec3::Y), Some(MixtureRegion { index: 7 * 6 + 2, normal: Vec3::Y }));
        assert_eq!(guide.locate(Vec3::NAN, Vec3::Y), None);
        assert_eq!(guide.locate(p, Vec3::ZERO), None);
    }

    #[test]
    fn learning_finds_the_light_and_the_scale() {
        let mut guide = guide(LearningRate::SimpleAverage);
        let region = guide.locate(Vec3::splat(0.25), Vec3::X).unwrap();
        for epoch in 0..6 {
            teach(&guide, region, 20_000, epoch);
            guide.rebuild_sampling();
        }
        let mixture = guide.mixture(region.index as usize);
        // ∫ 5·max(0, x)⁴ dω = 5·2π/5 = 2π.
        let scale = mixture.total_weight();
        assert!((scale - 2.0 * PI).abs() < 0.05 * 2.0 * PI, "S = {scale}");
        assert!(guide.pdf(region, Vec3::X) > 30.0 * guide.pdf(region, -Vec3::X));
        // Lambertian at normal +x, albedo 1: ∫ 5 x⁴ · x/π dω = 5/π · 2π/6 = 5/3.
        let lambert = |wi: Vec3, _: Vec3| wi.x.max(0.0) / PI;
        let mut rng = Pcg32::new(9, 9);
        let n = 4000;
        let mean: f64 =
            (0..n).map(|_| guide.estimate_integral(region, Vec3::X, &lambert, rng.next_vec2()) as f64).sum::<f64>()
                / n as f64;
        assert!((mean - 5.0 / 3.0).abs() < 0.05 * 5.0 / 3.0, "∫Q fs cos ≈ {mean}");
    }

    #[test]
    fn exponential_zero_keeps_one_replaces_and_simple_pools_batches() {
        for (rate, check) in [
            (LearningRate::Exponential { alpha: 0.0 }, "keep"),
            (LearningRate::Exponential { alpha: 1.0 }, "replace"),
            (LearningRate::SimpleAverage, "pool"),
        ] {
            let mut guide = guide(rate);
            let region = MixtureRegion { index: 0, normal: Vec3::Y };
            let before = *guide.mixture(0);
            // Two batches of constant targets 1 and 3 from uniform directions (pdf 1/4π).
            for target in [1.0f32, 3.0] {
                let mut rng = Pcg32::new(target as u64, 1);
                for _ in 0..1000 {
                    let d = UniformSphere.sample(rng.next_vec2()).direction;
                    guide.update(region, d, target);
                }
                guide.rebuild_sampling();
            }
            let scale = guide.mixture(0).total_weight() / (4.0 * PI);
            match check {
                "keep" => assert_eq!(guide.mixture(0).lobe(0), before.lobe(0)),
                "replace" => assert!((scale - 3.0).abs() < 1e-4, "{scale}"),
                _ => assert!((scale - 2.0).abs() < 1e-4, "{scale}"),
            }
            assert_eq!(guide.stats().accepted_updates, 2000);
        }
    }

    #[test]
    fn bad_updates_are_counted_or_ignored_and_change_nothing() {
        let mut guide = guide(LearningRate::SimpleAverage);
        let region = MixtureRegion { index: 3, normal: Vec3::Y };
        let before = *guide.mixture(3);
        assert_eq!(guide.update_sampled(region, Vec3::X, f32::NAN, 1.0), UpdateOutcome::RejectedNonFinite);
        assert_eq!(guide.update_sampled(region, Vec3::X, -1.0, 1.0), UpdateOutcome::RejectedNegative);
        for (d, pdf) in [(Vec3::NAN, 1.0), (Vec3::ZERO, 1.0), (Vec3::X, 0.0), (Vec3::X, f32::NAN), (Vec3::X, -1.0)] {
            assert_eq!(guide.update_sampled(region, d, 1.0, pdf), UpdateOutcome::OutsideDomain);
        }
        guide.rebuild_sampling();
        assert_eq!(*guide.mixture(3), before);
        let stats = guide.stats();
        assert_eq!((stats.rejected_non_finite, stats.rejected_negative, stats.accepted_updates), (1, 1, 0));
        // Huge weights saturate instead of overflowing.
        for _ in 0..100 {
            guide.update_sampled(region, Vec3::Y, f32::MAX, f32::MIN_POSITIVE);
        }
        guide.rebuild_sampling();
        assert!(guide.validate().is_ok());
        assert!(guide.pdf(region, Vec3::Y).is_finite());
    }

    #[test]
    fn sampling_keeps_to_the_normals_hemisphere_with_an_exact_pdf() {
        use crate::mixture::vmf::VmfLobe;
        use crate::validation::{chi_square_test, pdf_integral, ChiSquareSettings};
        let mut guide = guide(LearningRate::SimpleAverage);
        let normal = Vec3::new(0.3, 0.8, -0.52).normalize();
        let region = guide.locate(Vec3::splat(0.25), normal).unwrap();
        // One sharp lobe above the surface, one broad lobe mostly below it: unfolded, a
        // third of the samples would leave below the surface and end their paths.
        let lobes =
            [(VmfLobe::new(Vec3::new(0.5, 0.7, 0.1).normalize(), 40.0), 0.6), (VmfLobe::new(-normal, 2.0), 0.4)];
        guide.set_mixture(region.index as usize, VmfMixture::from_lobes(&lobes, 1.0));
        let distribution = guide.distribution(region);
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..10_000 {
            let s = distribution.sample(rng.next_vec2());
            assert!(s.direction.dot(normal) > 0.0, "{:?} below the surface", s.direction);
            assert!((s.pdf - distribution.pdf(s.direction)).abs() <= 1e-4 * s.pdf);
        }
        assert_eq!(distribution.pdf(-normal), 0.0);
        assert_eq!(distribution.pdf(Vec3::NAN), 0.0);
        // 32² cells four levels deep: the horizon's cut lies on a cell border (z = 0), so
        // this is exact to 1e-3 at 1/64 of the evaluations of 64 cells six levels deep.
        let total = pdf_integral(&|d| distribution.pdf(d), normal, 32, 4);
        assert!((total - 1.0).abs() < 1e-3, "∫ = {total}");
        let report = chi_square_test(&distribution, normal, &ChiSquareSettings::default());
        assert!(report.passes(0.01), "{report:?}");
    }

    #[test]
    fn memory_stays_within_the_budget() {
        for budget in [4 << 10, 100 << 10, 2 << 20] {
            for split_by_normal in [false, true] {
                let settings = GaussianMixtureSettings { budget_bytes: budget, split_by_normal, ..Default::default() };
                let guide = GaussianMixture::new(Vec3::ZERO, Vec3::new(3.0, 1.0, 2.0), settings).unwrap();
                assert!(guide.memory_bytes() <= budget, "{} > {budget}", guide.memory_bytes());
                // Whole near-cubic cells leave part of a small budget unused, never most of it.
                assert!(guide.memory_bytes() * 4 > budget, "{} wastes {budget}", guide.memory_bytes());
            }
        }
        let tiny = GaussianMixtureSettings { budget_bytes: 100, ..Default::default() };
        assert!(matches!(GaussianMixture::new(Vec3::ZERO, Vec3::ONE, tiny), Err(Error::BudgetTooSmall { .. })));
    }
}
