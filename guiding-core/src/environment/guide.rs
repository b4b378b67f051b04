//! [`EnvTileGuide`]: per grid cell, a learned importance per environment tile (and per
//! sun), and the distribution over directions it gives.

use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

use alloc::vec;
use alloc::vec::Vec;
use glam::{Vec2, Vec3};

use crate::atomic_f32;
use crate::cdf::{build_cdf, cdf_probability, sample_cdf};
use crate::cell_grid::CellGrid;
use crate::distribution::{DirectionSample, DirectionalDistribution};
use crate::error::Error;
use crate::update_rule::{classify_target, UpdateOutcome};

use super::settings::{EnvTileGuideSettings, ENTRY_BYTES};
use super::sun::SunDisk;
use super::tiles::EnvironmentTiles;

/// A cell of an [`EnvTileGuide`]'s grid: the region [`EnvTileGuide::locate`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EnvCell(pub u32);

/// What a cell's distribution is made of: tiles `0..tile_count`, then the sun (if any)
/// as lobe `tile_count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EnvLobe(pub u32);

/// A direction towards the environment drawn from a cell's distribution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit direction, world space.
    pub direction: Vec3,
    /// Density of `direction` under the whole distribution (every lobe that covers it),
    /// per steradian: what multiple importance sampling needs.
    pub pdf: f32,
    /// The lobe it came from, for [`EnvTileGuide::update`].
    pub lobe: EnvLobe,
    /// Density of `direction` given that lobe, per steradian.
    pub lobe_pdf: f32,
}

/// Learned environment sampling for next-event estimation: the map cut into tiles, a
/// regular grid over the scene, and in each cell a value V per tile learned from the
/// light that actually arrived there (V' = (1-α)V + α·target, α = 1/(1+n)), so sky
/// hidden behind walls is learned away. Sampling picks a lobe (a tile, or the sun) from
/// the cell's CDF — learned values mixed with power-proportional and uniform shares —
/// then a texel in the tile by luminance (or a point on the sun's disk).
///
/// ```
/// use guiding_core::environment::{EnvTileGuide, EnvTileGuideSettings, EnvironmentTiles};
/// use guiding_core::DirectionalDistribution;
/// use glam::{Vec2, Vec3};
///
/// let tiles = EnvironmentTiles::new(8, 4, &[1.0; 32], [4, 2])?;
/// let mut guide = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, None, EnvTileGuideSettings::default())?;
/// let cell = guide.locate(Vec3::splat(0.5)).expect("finite");
/// // Only light from straight up (+y) ever arrives in this cell.
/// for i in 0..1000 {
///     let s = guide.distribution(cell).sample_lobe(0.37 * i as f32 % 1.0, Vec2::new(0.5, 0.5));
///     guide.update(cell, &s, if s.direction.y > 0.0 { 1.0 } else { 0.0 });
/// }
/// guide.rebuild_sampling();
/// let up = guide.distribution(cell).pdf(Vec3::new(0.1, 0.9, 0.0).normalize());
/// let down = guide.distribution(cell).pdf(Vec3::new(0.1, -0.9, 0.0).normalize());
/// assert!(up > 5.0 * down && down > 0.0);
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Debug)]
pub struct EnvTileGuide {
    pub(super) settings: EnvTileGuideSettings,
    /// The box it was built over (scene units).
    pub(super) bounds: (Vec3, Vec3),
    grid: CellGrid,
    pub(super) tiles: EnvironmentTiles,
    pub(super) sun: Option<SunDisk>,
    lobes: usize,
    /// Per lobe: its share of the total power.
    pub(super) power_share: Vec<f32>,
    /// Lobes with power > 0 (the uniform share goes to these).
    lit_lobes: usize,
    /// Per (cell, lobe): V (f32 bits) and the updates it took.
    pub(super) values: Vec<AtomicU32>,
    pub(super) updates: Vec<AtomicU32>,
    /// Per (cell, lobe): the lobe CDF of the last rebuild.
    cdf: Vec<f32>,
    pub(super) rejected: AtomicUsize,
}

impl EnvTileGuide {
    /// A guide over the box `low..high` (scene units) for an environment of `tiles` and
    /// an optional `sun`. Errors name the setting or bound that is wrong.
    pub fn new(
        low: Vec3,
        high: Vec3,
        tiles: EnvironmentTiles,
        sun: Option<SunDisk>,
        settings: EnvTileGuideSettings,
    ) -> Result<Self, Error> {
        settings.validate()?;
        let lobes = tiles.tile_count() + usize::from(sun.is_some());
        let grid = CellGrid::new(low, high, settings.resolution, settings.budget_bytes, lobes * ENTRY_BYTES)?;
        let powers: Vec<f64> =
            (0..tiles.tile_count()).map(|t| tiles.power(t) as f64).chain(sun.map(|s| s.power() as f64)).collect();
        let total: f64 = powers.iter().sum();
        let lit_lobes = powers.iter().filter(|&&p| p > 0.0).count();
        let power_share =
            powers.iter().map(|&p| if total > 0.0 { (p / total) as f32 } else { 1.0 / lobes as f32 }).collect();
        let entries = grid.cell_count() * lobes;
        let mut guide = Self {
            settings,
            bounds: (low, high),
            grid,
            tiles,
            sun,
            lobes,
            power_share,
            lit_lobes,
            values: (0..entries).map(|_| atomic_f32::new(0.0)).collect(),
            updates: (0..entries).map(|_| AtomicU32::new(0)).collect(),
            cdf: vec![0.0; entries],
            rejected: AtomicUsize::new(0),
        };
        guide.rebuild_sampling();
        Ok(guide)
    }

    /// The cell holding `position`; points outside the bounds use the nearest cell.
    /// `None` for a non-finite position.
    #[inline]
    pub fn locate(&self, position: Vec3) -> Option<EnvCell> {
        self.grid.cell(position).map(EnvCell)
    }

    /// The distribution over directions of `cell`.
    #[inline]
    pub fn distribution(&self, cell: EnvCell) -> EnvDistribution<'_> {
        let start = cell.0 as usize * self.lobes;
        EnvDistribution { guide: self, cdf: &self.cdf[start..start + self.lobes] }
    }

    /// The sun's lobe, if there is a sun.
    pub fn sun_lobe(&self) -> Option<EnvLobe> {
        self.sun.map(|_| EnvLobe(self.tiles.tile_count() as u32))
    }

    /// Learns from `sample`, drawn from `cell`'s distribution: `integrand` is
    /// ‖f·L·cos θ‖∞ × visibility at its direction (radiance × BSDF, not divided by any
    /// pdf), with L the radiance of the sample's lobe alone (the sky's for a tile, the
    /// sun's for the sun). The target is integrand / p(direction | lobe), a one-sample
    /// estimate of the lobe's whole contribution. NaN, infinite and negative integrands
    /// are rejected and counted; a cell, lobe or lobe density that no sample of this guide
    /// has is `OutsideDomain`. Where many threads learn at once,
    /// [`record`](Self::record) into each thread's [`EnvRecords`](super::EnvRecords) and
    /// [`splat`](Self::splat) them between passes instead: no locked writes on shared lines.
    pub fn update(&self, cell: EnvCell, sample: &EnvSample, integrand: f32) -> UpdateOutcome {
        match self.target(cell, sample, integrand) {
            Ok((index, target)) => {
                atomic_f32::running_average(&self.values[index], &self.updates[index], target);
                UpdateOutcome::Accepted
            }
            Err(outcome) => outcome,
        }
    }

    /// The entry `sample` from `cell` teaches and its target (see [`update`](Self::update)),
    /// or the outcome that refuses it; a rejected integrand is counted.
    #[inline]
    pub(super) fn target(
        &self,
        cell: EnvCell,
        sample: &EnvSample,
        integrand: f32,
    ) -> Result<(usize, f32), UpdateOutcome> {
        let (cell, lobe, conditional_pdf) = (cell.0 as usize, sample.lobe.0 as usize, sample.lobe_pdf);
        let valid_pdf = conditional_pdf.is_finite() && conditional_pdf > 0.0;
        if cell >= self.grid.cell_count() || lobe >= self.lobes || !valid_pdf {
            return Err(UpdateOutcome::OutsideDomain);
        }
        let integrand = classify_target(integrand).inspect_err(|_| {
            self.rejected.fetch_add(1, Ordering::Relaxed);
        })?;
        Ok((cell * self.lobes + lobe, integrand / conditional_pdf))
    }

    /// Adds what `other` learned (another process of the same scene) to this guide and
    /// rebuilds: per (cell, lobe) the values are averaged by their update counts and the
    /// counts add, so the merge is exact. Both must have the same bounds, environment
    /// (tiles, sun) and settings; otherwise nothing changes and [`Error::Incompatible`]
    /// names what differs.
    pub fn merge(&mut self, other: &EnvTileGuide) -> Result<(), Error> {
        if self.settings != other.settings {
            return Err(Error::Incompatible { what: "settings" });
        }
        if self.bounds != other.bounds || self.grid.resolution() != other.grid.resolution() {
            return Err(Error::Incompatible { what: "bounds" });
        }
        if self.power_share != other.power_share || self.tiles.size() != other.tiles.size() {
            return Err(Error::Incompatible { what: "environment" });
        }
        atomic_f32::merge_running_averages(&self.values, &self.updates, &other.values, &other.updates);
        self.rejected.fetch_add(other.rejected.load(Ordering::Relaxed), Ordering::Relaxed);
        self.rebuild_sampling();
        Ok(())
    }

    /// Forgets everything learned: every value and update count back to 0 (sampling by
    /// power and the uniform share alone, as [`new`](Self::new) made it).
    pub fn reset(&mut self) {
        for counter in self.values.iter().chain(&self.updates) {
            counter.store(0, Ordering::Relaxed);
        }
        self.rejected.store(0, Ordering::Relaxed);
        self.rebuild_sampling();
    }

    /// Rebuilds every cell's lobe CDF from what it learned: probability
    /// (1 - power_mix - uniform_mix)·V/ΣV + power_mix·power share + uniform_mix/lit lobes
    /// (cells that learned nothing yet use the power and uniform shares alone). Lobes
    /// without power (black tiles) keep probability 0: they bring no light. Call between
    /// passes.
    pub fn rebuild_sampling(&mut self) {
        let (power_mix, uniform_mix) = (self.settings.power_mix as f64, self.settings.uniform_mix as f64);
        let uniform = uniform_mix / self.lit_lobes.max(1) as f64;
        for cell in 0..self.grid.cell_count() {
            let row = cell * self.lobes..(cell + 1) * self.lobes;
            let learned = &self.values[row.clone()];
            let total: f64 = learned.iter().map(|v| atomic_f32::load(v) as f64).sum();
            let learned_mix = if total > 0.0 { 1.0 - power_mix - uniform_mix } else { 0.0 };
            let power_mix = 1.0 - uniform_mix - learned_mix;
            let weight = |lobe: usize| {
                let share = self.power_share[lobe] as f64;
                if share <= 0.0 && self.lit_lobes > 0 {
                    return 0.0;
                }
                let value = if total > 0.0 { atomic_f32::load(&learned[lobe]) as f64 / total } else { 0.0 };
                (learned_mix * value + power_mix * share + uniform) as f32
            };
            build_cdf(&mut self.cdf[row], 0.0, weight);
        }
    }

    /// The tiles it samples.
    pub fn tiles(&self) -> &EnvironmentTiles {
        &self.tiles
    }

    /// The sun it samples, if any.
    pub fn sun(&self) -> Option<&SunDisk> {
        self.sun.as_ref()
    }

    /// Entries in the tables: cells × lobes.
    #[inline]
    pub(super) fn entry_count(&self) -> usize {
        self.values.len()
    }

    /// Lobes per cell: tiles, plus one for the sun.
    pub fn lobe_count(&self) -> usize {
        self.lobes
    }

    /// Cells along x, y and z.
    pub fn resolution(&self) -> [u32; 3] {
        self.grid.resolution()
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.grid.cell_count()
    }

    /// Bytes of the per-cell tables (what `budget_bytes` bounds).
    pub fn table_bytes(&self) -> usize {
        self.grid.cell_count() * self.lobes * ENTRY_BYTES
    }

    /// Bytes held in all: per-cell tables, the texel CDFs and the lobe shares.
    pub fn memory_bytes(&self) -> usize {
        self.table_bytes() + self.tiles.memory_bytes() + self.lobes * 4 + core::mem::size_of::<Self>()
    }

    /// Updates rejected for a NaN, infinite or negative integrand.
    pub fn rejected_updates(&self) -> usize {
        self.rejected.load(Ordering::Relaxed)
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &EnvTileGuideSettings {
        &self.settings
    }

    /// What the guide learned as bytes (versioned, checksummed), with its settings,
    /// bounds and a fingerprint of the environment (map size, tiles, each lobe's power);
    /// the environment itself is the scene's and is not stored. Call between passes.
    pub fn to_bytes(&self) -> Vec<u8> {
        super::serialize::encode(self)
    }

    /// Reads a guide written by [`to_bytes`](Self::to_bytes) for the environment of
    /// `tiles` and `sun`, which must be the one it learned (else
    /// [`Error::Incompatible`] naming the `environment`). Every field is checked
    /// (damaged bytes give an error, never a panic); the lobe CDFs are rebuilt.
    pub fn from_bytes(bytes: &[u8], tiles: EnvironmentTiles, sun: Option<SunDisk>) -> Result<Self, Error> {
        super::serialize::decode(bytes, tiles, sun)
    }
}

/// One cell's distribution over directions towards the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvDistribution<'a> {
    guide: &'a EnvTileGuide,
    cdf: &'a [f32],
}

impl EnvDistribution<'_> {
    /// Draws a lobe from `u_lobe`, then a direction in it from `u` (three uniform numbers
    /// in [0, 1), so the direction keeps all the precision of `u`).
    #[inline]
    pub fn sample_lobe(&self, u_lobe: f32, u: Vec2) -> EnvSample {
        let (lobe, _) = sample_cdf(self.cdf, u_lobe);
        let tiles = &self.guide.tiles;
        let sun_lobe = tiles.tile_count();
        let (direction, lobe_pdf, pdf) = match self.guide.sun {
            Some(sun) if lobe == sun_lobe => {
                let direction = sun.sample(u);
                (direction, sun.pdf(), self.pdf(direction))
            }
            _ => {
                // The tile and texel are known: only the sun may overlap them.
                let (direction, lobe_pdf) = tiles.sample_in_tile(lobe, u);
                let mut pdf = cdf_probability(self.cdf, lobe) * lobe_pdf;
                if let Some(sun) = self.guide.sun.filter(|sun| sun.contains(direction)) {
                    pdf += cdf_probability(self.cdf, sun_lobe) * sun.pdf();
                }
                (direction, lobe_pdf, pdf)
            }
        };
        EnvSample { direction, pdf, lobe: EnvLobe(lobe as u32), lobe_pdf }
    }

    /// The probability of picking `lobe`.
    pub fn lobe_probability(&self, lobe: EnvLobe) -> f32 {
        if lobe.0 as usize >= self.cdf.len() {
            return 0.0;
        }
        cdf_probability(self.cdf, lobe.0 as usize)
    }
}

impl DirectionalDistribution for EnvDistribution<'_> {
    /// Picks the lobe from `u.x` and reuses the rest of it inside the lobe (fewer bits of
    /// precision than [`sample_lobe`](EnvDistribution::sample_lobe), the same distribution).
    fn sample(&self, u: Vec2) -> DirectionSample {
        let (_, rest) = sample_cdf(self.cdf, u.x);
        let s = self.sample_lobe(u.x, Vec2::new(rest, u.y));
        DirectionSample { direction: s.direction, pdf: s.pdf }
    }

    /// Σ over the lobes covering `direction` of P(lobe)·p(direction | lobe).
    #[inline]
    fn pdf(&self, direction: Vec3) -> f32 {
        let tiles = &self.guide.tiles;
        let (tile, in_tile) = tiles.tile_and_pdf(direction);
        let mut pdf = cdf_probability(self.cdf, tile) * in_tile;
        if let Some(sun) = &self.guide.sun {
            if sun.contains(direction) {
                pdf += cdf_probability(self.cdf, tiles.tile_count()) * sun.pdf();
            }
        }
        pdf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;
    use crate::validation::{chi_square_test, ChiSquareSettings};

    fn sky(width: usize, height: usize) -> Vec<f32> {
        (0..width * height)
            .map(|i| {
                if i % 11 == 4 {
                    20.0
                } else if i % 13 == 0 {
                    0.0
                } else {
                    0.5 + (i % 3) as f32
                }
            })
            .collect()
    }

    /// A guide over the unit cube whose cell at the origin learned that only light from
    /// above +y·0.3 arrives (a window in the ceiling).
    fn learned_guide(sun: bool) -> (EnvTileGuide, EnvCell) {
        let tiles = EnvironmentTiles::new(64, 32, &sky(64, 32), [16, 8]).unwrap();
        let sun = sun.then(|| SunDisk::new(Vec3::new(0.4, 0.9, -0.2), 2f32.to_radians(), 500.0).unwrap());
        let settings = EnvTileGuideSettings { resolution: Some([2, 2, 2]), ..Default::default() };
        let mut guide = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, sun, settings).unwrap();
        let cell = guide.locate(Vec3::splat(0.1)).unwrap();
        let luminance = sky(64, 32);
        let mut rng = Pcg32::new(5, 6);
        for _ in 0..20_000 {
            let s = guide.distribution(cell).sample_lobe(rng.next_f32(), rng.next_vec2());
            // The lobe's own radiance times a cosine, where it is visible.
            let radiance = match guide.sun() {
                Some(sun) if Some(s.lobe) == guide.sun_lobe() => sun.luminance(),
                _ => {
                    let (column, row) = super::super::lat_long::texel_of_direction(s.direction, 64, 32);
                    luminance[row * 64 + column]
                }
            };
            let visible = s.direction.y > 0.3;
            guide.update(cell, &s, if visible { radiance * s.direction.y } else { 0.0 });
        }
        guide.rebuild_sampling();
        (guide, cell)
    }

    #[test]
    fn reset_gives_the_guide_made_fresh() {
        let (mut learned, cell) = learned_guide(true);
        let tiles = EnvironmentTiles::new(64, 32, &sky(64, 32), [16, 8]).unwrap();
        let sun = SunDisk::new(Vec3::new(0.4, 0.9, -0.2), 2f32.to_radians(), 500.0).unwrap();
        let settings = EnvTileGuideSettings { resolution: Some([2, 2, 2]), ..Default::default() };
        let fresh = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, Some(sun), settings).unwrap();
        assert_ne!(learned.to_bytes(), fresh.to_bytes());
        learned.reset();
        assert_eq!(learned.to_bytes(), fresh.to_bytes());
        let d = Vec3::new(0.3, 0.5, 0.8).normalize();
        assert_eq!(learned.distribution(cell).pdf(d), fresh.distribution(cell).pdf(d));
    }

    #[test]
    fn merging_two_halves_learns_what_one_guide_learns_from_all() {
        let make = || {
            let tiles = EnvironmentTiles::new(32, 16, &sky(32, 16), [8, 4]).unwrap();
            let sun = SunDisk::new(Vec3::new(0.4, 0.9, -0.2), 2f32.to_radians(), 500.0).unwrap();
            let settings = EnvTileGuideSettings { resolution: Some([2, 2, 2]), ..Default::default() };
            EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, Some(sun), settings).unwrap()
        };
        let (mut first, second, mut whole) = (make(), make(), make());
        let mut rng = Pcg32::new(3, 3);
        for i in 0..20_000 {
            let cell = whole.locate(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())).unwrap();
            let s = whole.distribution(cell).sample_lobe(rng.next_f32(), rng.next_vec2());
            let integrand = if s.direction.y > 0.2 { rng.next_f32() } else { 0.0 };
            whole.update(cell, &s, integrand);
            (if i % 2 == 0 { &first } else { &second }).update(cell, &s, integrand);
        }
        whole.rebuild_sampling();
        first.merge(&second).unwrap();
        for cell in 0..whole.cell_count() as u32 {
            for lobe in 0..whole.lobe_count() as u32 {
                let merged = first.distribution(EnvCell(cell)).lobe_probability(EnvLobe(lobe));
                let all = whole.distribution(EnvCell(cell)).lobe_probability(EnvLobe(lobe));
                assert!((merged - all).abs() <= 1e-5 * all.max(1e-3), "cell {cell} lobe {lobe}: {merged} vs {all}");
            }
        }
        let (other, _) = learned_guide(true);
        assert!(matches!(first.merge(&other), Err(Error::Incompatible { .. })));
    }

    /// ∫ pdf dω, the tiles' part by the midpoint rule on a grid aligned with the texels
    /// (exact: pdf·sin θ is constant in a texel), plus the sun's lobe probability.
    fn pdf_integral(guide: &EnvTileGuide, cell: EnvCell) -> f64 {
        let distribution = guide.distribution(cell);
        let sun_share = guide.sun_lobe().map_or(0.0, |lobe| distribution.lobe_probability(lobe));
        let (nu, nv) = (64 * 4, 32 * 4);
        let mut total = 0.0f64;
        for i in 0..nv {
            for j in 0..nu {
                let uv = Vec2::new((j as f32 + 0.5) / nu as f32, (i as f32 + 0.5) / nv as f32);
                let d = super::super::lat_long::direction_of_uv(uv);
                let sun_part = match guide.sun() {
                    Some(sun) if sun.contains(d) => sun_share * sun.pdf(),
                    _ => 0.0,
                };
                let sin_theta = libm::sin(core::f64::consts::PI * uv.y as f64);
                total += (distribution.pdf(d) - sun_part) as f64 * sin_theta;
            }
        }
        total * 2.0 * core::f64::consts::PI * core::f64::consts::PI / (nu * nv) as f64 + sun_share as f64
    }

    #[test]
    fn the_pdf_integrates_to_one() {
        for sun in [false, true] {
            let (guide, cell) = learned_guide(sun);
            let far = guide.locate(Vec3::ONE).unwrap();
            for c in [cell, far] {
                let integral = pdf_integral(&guide, c);
                assert!((integral - 1.0).abs() < 1e-4, "sun {sun}: ∫ pdf = {integral}");
            }
        }
    }

    #[test]
    fn sampling_matches_the_pdf_by_chi_square() {
        let (guide, cell) = learned_guide(true);
        let distribution = guide.distribution(cell);
        let settings = ChiSquareSettings { theta_bins: 24, phi_bins: 48, ..Default::default() };
        let report = chi_square_test(&distribution, Vec3::Y, &settings);
        assert!(report.passes(0.01), "{report:?}");
        // Learning moved probability up: directions below the window became rare.
        let (up, down) = (Vec3::new(0.1, 0.9, 0.2).normalize(), Vec3::new(0.1, -0.9, 0.2).normalize());
        assert!(distribution.pdf(up) > 4.0 * distribution.pdf(down));
        // The three-number sampler draws the same directions' densities.
        let mut rng = Pcg32::new(2, 3);
        for _ in 0..10_000 {
            let s = distribution.sample_lobe(rng.next_f32(), rng.next_vec2());
            assert!(s.pdf > 0.0 && s.pdf == distribution.pdf(s.direction));
        }
    }

    #[test]
    fn a_deliberately_wrong_pdf_fails_chi_square() {
        struct Skewed<'a>(EnvDistribution<'a>);
        impl DirectionalDistribution for Skewed<'_> {
            fn sample(&self, u: Vec2) -> DirectionSample {
                self.0.sample(u)
            }
            fn pdf(&self, d: Vec3) -> f32 {
                self.0.pdf(d) * if d.x > 0.0 { 1.1 } else { 0.9 }
            }
        }
        let (guide, cell) = learned_guide(true);
        let settings = ChiSquareSettings { theta_bins: 24, phi_bins: 48, ..Default::default() };
        assert!(!chi_square_test(&Skewed(guide.distribution(cell)), Vec3::Y, &settings).passes(0.01));
    }

    #[test]
    fn the_sun_is_sampled_on_its_own_and_never_lost() {
        let (guide, cell) = learned_guide(true);
        let distribution = guide.distribution(cell);
        let sun = *guide.sun().unwrap();
        let lobe = guide.sun_lobe().unwrap();
        assert!(distribution.lobe_probability(lobe) > 0.1, "{}", distribution.lobe_probability(lobe));
        // An unlearned cell: power shares; the sun holds 500·2π(1 − cos 2°) of the power.
        let far = guide.distribution(guide.locate(Vec3::ONE).unwrap());
        assert!(far.lobe_probability(lobe) > 0.0);
        let d = sun.sample(Vec2::new(0.5, 0.5));
        assert!(distribution.pdf(d) >= distribution.lobe_probability(lobe) * sun.pdf());
    }

    #[test]
    fn black_tiles_get_nothing_and_lit_ones_never_zero() {
        // The lower half of the map is black.
        let (w, h) = (32, 16);
        let luminance: Vec<f32> = (0..w * h).map(|i| if i / w < h / 2 { 1.0 } else { 0.0 }).collect();
        let tiles = EnvironmentTiles::new(w, h, &luminance, [8, 4]).unwrap();
        let mut guide = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, None, Default::default()).unwrap();
        let cell = guide.locate(Vec3::ZERO).unwrap();
        // Only one tile ever brings light.
        for _ in 0..100 {
            let (direction, lobe_pdf) = guide.tiles().sample_in_tile(3, Vec2::splat(0.5));
            guide.update(cell, &EnvSample { direction, pdf: 0.0, lobe: EnvLobe(3), lobe_pdf }, 1.0);
        }
        guide.rebuild_sampling();
        let distribution = guide.distribution(cell);
        for t in 0..32 {
            let p = distribution.lobe_probability(EnvLobe(t));
            assert_eq!(p > 0.0, t < 16, "tile {t}: {p}");
        }
        assert!(distribution.lobe_probability(EnvLobe(3)) > 0.7);
    }

    #[test]
    fn bad_updates_are_rejected_and_counted() {
        let (guide, cell) = learned_guide(true);
        let s = guide.distribution(cell).sample_lobe(0.5, Vec2::splat(0.5));
        assert_eq!(guide.update(cell, &s, f32::NAN), UpdateOutcome::RejectedNonFinite);
        assert_eq!(guide.update(cell, &s, -1.0), UpdateOutcome::RejectedNegative);
        assert_eq!(guide.update(cell, &EnvSample { lobe: EnvLobe(999), ..s }, 1.0), UpdateOutcome::OutsideDomain);
        assert_eq!(guide.update(EnvCell(999), &s, 1.0), UpdateOutcome::OutsideDomain);
        for lobe_pdf in [0.0, f32::NAN, f32::INFINITY] {
            assert_eq!(guide.update(cell, &EnvSample { lobe_pdf, ..s }, 1.0), UpdateOutcome::OutsideDomain);
        }
        assert_eq!(guide.rejected_updates(), 2);
        assert_eq!(guide.locate(Vec3::NAN), None);
    }

    #[test]
    fn the_budget_sets_the_resolution_and_is_kept() {
        let tiles = EnvironmentTiles::new(64, 32, &sky(64, 32), [16, 8]).unwrap();
        let settings = EnvTileGuideSettings { budget_bytes: 256 << 10, ..Default::default() };
        let guide = EnvTileGuide::new(Vec3::ZERO, Vec3::new(4.0, 2.6, 5.0), tiles, None, settings).unwrap();
        assert!(guide.cell_count() >= 100, "{:?}", guide.resolution());
        assert!(guide.table_bytes() <= settings.budget_bytes);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        /// Whatever was learned (zeros, huge values), every lit tile and the sun keep a
        /// positive probability in every cell, and the lobe probabilities sum to one.
        #[test]
        fn no_lit_lobe_is_ever_at_zero_probability(
            updates in proptest::collection::vec((0u32..33, 0.0f32..1e30, 0.0f32..1.0, 0.0f32..1.0), 0..200),
            sun_luminance in proptest::prop_oneof![proptest::prelude::Just(0.0f32), 1e-20f32..1e-10, 1.0f32..1e6],
        ) {
            let tiles = EnvironmentTiles::new(32, 16, &sky(32, 16), [8, 4]).unwrap();
            let sun = SunDisk::new(Vec3::new(0.0, 1.0, 1.0), 1f32.to_radians(), sun_luminance).unwrap();
            let settings = EnvTileGuideSettings { resolution: Some([2, 1, 1]), ..Default::default() };
            let mut guide = EnvTileGuide::new(Vec3::ZERO, Vec3::ONE, tiles, Some(sun), settings).unwrap();
            let cell = guide.locate(Vec3::ZERO).unwrap();
            for &(lobe, integrand, u, v) in &updates {
                let lobe = EnvLobe(lobe % 33);
                let (direction, lobe_pdf) = if lobe.0 == 32 {
                    (sun.sample(Vec2::new(u, v)), sun.pdf())
                } else {
                    guide.tiles().sample_in_tile(lobe.0 as usize, Vec2::new(u, v))
                };
                guide.update(cell, &EnvSample { direction, pdf: 0.0, lobe, lobe_pdf }, integrand);
            }
            guide.rebuild_sampling();
            for c in 0..guide.cell_count() as u32 {
                let distribution = guide.distribution(EnvCell(c));
                let mut total = 0.0f64;
                for lobe in 0..33 {
                    let p = distribution.lobe_probability(EnvLobe(lobe));
                    let lit = if lobe == 32 { sun_luminance > 0.0 } else { guide.tiles().power(lobe as usize) > 0.0 };
                    proptest::prop_assert!(!lit || p > 0.0, "cell {c}, lobe {lobe}: {p}");
                    total += p as f64;
                }
                proptest::prop_assert!((total - 1.0).abs() < 1e-6, "cell {c}: {total}");
            }
        }
    }
}
