//! Russian roulette and splitting that weigh what a path's continuation is worth against
//! what it costs (efficiency-aware Russian roulette and splitting, Rath et al. 2022).
//!
//! Giving a path of throughput T q continuations on average at a vertex (q < 1: Russian
//! roulette; q > 1: splitting) changes its pixel's variance by about T²·M·(1/q − 1), M the
//! second moment of what one continuation brings per unit throughput, and its cost by
//! (q − 1) times the continuation's cost C. Over an image whose relative variance per
//! sample is v and whose paths cost C̄ each, the best q for relative error is
//! T·√(M·C̄/C) / (I·√v), I the pixel. Where continuations are rare but bright (light
//! through a gap) M is large against their mean, and paths go on, or split, where
//! throughput-based roulette would end them; where they bring little and cost much, paths
//! end early, whatever their throughput.
//!
//! Per cell of a coarse grid over the scene, and per side a surface faces there (the
//! normal's largest axis and its sign: the two faces of a wall between a lit room and a
//! dark one learn apart), it learns per unit throughput arriving at a vertex the radiance
//! the path gathered from the vertex on without the vertex's emission (`outgoing`: a
//! pixel estimate where the renderer has none), the square of the part its continuation
//! brought (next-event estimation at the vertex left out), and the cost of going on.
//! The factor reads only what the last [`rebuild_sampling`] made of them: learning
//! during a pass changes nothing a path of that pass reads.
//!
//! [`rebuild_sampling`]: EfficiencyRoulette::rebuild_sampling

use alloc::vec::Vec;
use core::sync::atomic::AtomicU32;

use glam::Vec3;

use crate::atomic_f32;
use crate::coarse_grid::CoarseGrid;
use crate::error::{require, Error};

/// Samples a cell's side needs before its means decide anything.
const MIN_SAMPLES: f32 = 16.0;

/// The least survival probability the roulette gives: the means are learned from few,
/// noisy paths, and one that underestimates what a continuation brings would otherwise
/// give the rare survivor a weight without bound.
pub const MIN_SURVIVAL: f32 = 0.05;

/// The most copies a path splits into at one vertex: a mean learned from few paths that
/// overestimates what a continuation brings would otherwise multiply a path's cost
/// without bound.
pub const MAX_SPLIT: f32 = 4.0;

/// The sides a cell tells apart: ±x, ±y, ±z.
const SIDES: usize = 6;

/// What a cell side learns: Σ outgoing, Σ continuation², the samples, Σ cost of the
/// continuations that went on and their count.
const SUMS: usize = 5;

/// Per cell side of a grid over the scene, what paths passing there brought and cost,
/// which sets how many continuations they get.
///
/// Cell sides are kept side-major (all cells' +x side, then all cells' −x side, …), and
/// within a side the cells in layers across the side's axis: the vertices on one wall
/// read one side of one layer of cells, which is consecutive. The roulette is read at
/// every vertex of a frozen pass, and with the sides of a cell together its reads missed
/// the cache (cornell 128², 4 % of guided-nee's time).
#[derive(Debug)]
pub struct EfficiencyRoulette {
    grid: CoarseGrid,
    /// Per cell side the sums learned so far (f32 bits, learning).
    sums: Vec<[AtomicU32; SUMS]>,
    /// Per cell side the mean outgoing radiance of the last rebuild (negative where too
    /// few samples were learned): the pixel estimate, read at a path's first vertex.
    outgoing: Vec<f32>,
    /// Per cell side the roots the continuations are decided with, from the last
    /// rebuild: √M and √(M/C), M the continuation's second moment and C the cost of
    /// going on (√M negative where too few samples were learned; √(M/C) negative where
    /// no cost was learned).
    roots: Vec<[f32; 2]>,
}

/// Where a vertex's samples go and its means come from: a cell side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RouletteCell(u32);

/// What the continuations weigh a path against: its pixel and the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RouletteImage {
    /// The pixel as the error weighs it (luminance; for relative error √(I² + ε)), > 0.
    pub pixel: f32,
    /// The image's relative variance per sample (mean over pixels of a sample's variance
    /// over the squared pixel), > 0.
    pub relative_variance: f32,
    /// A path's mean cost, in the unit of the costs learned (e.g. rays), > 0; or 0 to
    /// leave cost out.
    pub path_cost: f32,
}

/// A path's [`RouletteImage`] reduced to the factors its continuations are weighed by,
/// once per path ([`RouletteImage::scale`]): a vertex then multiplies, where the image's
/// roots and quotient were otherwise taken at every vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RouletteScale {
    /// 1 / (I·√v).
    per_root_moment: f32,
    /// √C̄ / (I·√v), or a negative value where cost is left out.
    per_root_moment_per_cost: f32,
}

impl RouletteImage {
    /// The factors of this pixel and image, or `None` where it holds no usable pixel or
    /// variance (the renderer's own roulette decides).
    #[inline]
    pub fn scale(&self) -> Option<RouletteScale> {
        let usable = self.pixel > 0.0 && self.relative_variance > 0.0 && self.relative_variance.is_finite();
        if !usable {
            return None;
        }
        let per_root_moment = 1.0 / (self.pixel * libm::sqrtf(self.relative_variance));
        let per_root_moment_per_cost =
            if self.path_cost > 0.0 { libm::sqrtf(self.path_cost) * per_root_moment } else { -1.0 };
        Some(RouletteScale { per_root_moment, per_root_moment_per_cost })
    }
}

impl EfficiencyRoulette {
    /// A grid over `low..high` with `resolution` (1..=128) cells along the longest side
    /// and the other sides in proportion. Nothing is known until learned.
    ///
    /// ```
    /// use guiding_core::{glam::Vec3, EfficiencyRoulette, RouletteImage};
    /// let mut roulette = EfficiencyRoulette::new(Vec3::ZERO, Vec3::ONE, 8).unwrap();
    /// let cell = roulette.locate(Vec3::splat(0.5), Vec3::Z).unwrap();
    /// for _ in 0..32 {
    ///     roulette.record(cell, 1.0, 0.5, Some(3.0));
    /// }
    /// roulette.rebuild_sampling();
    /// let image = RouletteImage { pixel: 1.0, relative_variance: 4.0, path_cost: 3.0 };
    /// // √(M = 0.25) / (1 · √4) = 0.25 at throughput 1.
    /// let scale = image.scale().unwrap();
    /// assert!((roulette.continuations(cell, 1.0, scale).unwrap() - 0.25).abs() < 1e-6);
    /// ```
    pub fn new(low: Vec3, high: Vec3, resolution: u32) -> Result<Self, Error> {
        require((1..=128).contains(&resolution), "roulette_resolution", resolution as f64, "in 1..=128")?;
        let grid = CoarseGrid::new(low, high, resolution)?;
        let count = grid.len() * SIDES;
        Ok(Self {
            grid,
            sums: (0..count).map(|_| core::array::from_fn(|_| atomic_f32::new(0.0))).collect(),
            outgoing: alloc::vec![-1.0; count],
            roots: alloc::vec![[-1.0, -1.0]; count],
        })
    }

    /// The cell side of a vertex at `point` whose surface faces `normal` (the side the
    /// path arrived from; clamped into the grid); `None` for a non-finite point or normal.
    #[inline]
    pub fn locate(&self, point: Vec3, normal: Vec3) -> Option<RouletteCell> {
        if !normal.is_finite() {
            return None;
        }
        let a = normal.abs();
        let axis = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let side = 2 * axis + u32::from(normal[axis as usize] < 0.0);
        let cell = self.grid.cell_in_layers(point, axis)?;
        Some(RouletteCell(side * self.grid.len() as u32 + cell as u32))
    }

    /// The radiance a path's pixel is expected to get from a first vertex in `cell` that
    /// showed the camera `emitted` (luminance): `None` where too little was learned there.
    #[inline]
    pub fn pixel_estimate(&self, cell: RouletteCell, emitted: f32) -> Option<f32> {
        let outgoing = self.outgoing[cell.0 as usize];
        (outgoing >= 0.0).then_some(emitted + outgoing)
    }

    /// How many continuations a path of throughput `throughput` (luminance) at a vertex
    /// in `cell` should have on average: T·√(M·C̄/C) / (I·√v) (see the module), clamped
    /// to [[`MIN_SURVIVAL`], [`MAX_SPLIT`]], `scale` the path's pixel and image
    /// ([`RouletteImage::scale`]). Below 1 it is the survival probability of Russian
    /// roulette; above 1 the path splits into that many copies on average (a renderer
    /// that does not split takes 1). `None` where too little was learned there (the
    /// renderer's own roulette decides).
    #[inline]
    pub fn continuations(&self, cell: RouletteCell, throughput: f32, scale: RouletteScale) -> Option<f32> {
        let [root_moment, root_moment_per_cost] = self.roots[cell.0 as usize];
        if root_moment < 0.0 || !throughput.is_finite() {
            return None;
        }
        let q = if root_moment_per_cost >= 0.0 && scale.per_root_moment_per_cost >= 0.0 {
            throughput * root_moment_per_cost * scale.per_root_moment_per_cost
        } else {
            throughput * root_moment * scale.per_root_moment
        };
        Some(if q.is_nan() { 1.0 } else { q.clamp(MIN_SURVIVAL, MAX_SPLIT) })
    }

    /// Learns one vertex of a finished path in `cell`: the radiance it gathered from the
    /// vertex on without the vertex's emission (`outgoing`) and the part its continuation
    /// brought (`continuation`), each per unit throughput at the vertex (luminance, ≥ 0),
    /// and, where the path went on past the vertex, what that cost (`cost`, > 0, in the
    /// unit of [`RouletteImage::path_cost`]). Non-finite or negative values are not
    /// learned. Lock-free; safe from many threads.
    pub fn record(&self, cell: RouletteCell, outgoing: f32, continuation: f32, cost: Option<f32>) {
        let valid = |v: f32| v.is_finite() && v >= 0.0;
        if !(valid(outgoing) && valid(continuation)) {
            return;
        }
        let Some(sums) = self.sums.get(cell.0 as usize) else { return };
        atomic_f32::update(&sums[0], |s| (s + outgoing).min(f32::MAX));
        atomic_f32::update(&sums[1], |s| (s + continuation * continuation).min(f32::MAX));
        atomic_f32::update(&sums[2], |n| n + 1.0);
        if let Some(cost) = cost.filter(|c| c.is_finite() && *c > 0.0) {
            atomic_f32::update(&sums[3], |s| (s + cost).min(f32::MAX));
            atomic_f32::update(&sums[4], |n| n + 1.0);
        }
    }

    /// Makes what was learned so far the means the continuations are decided with. The means
    /// estimate expectations that do not depend on how directions were drawn, so every
    /// sample keeps counting.
    pub fn rebuild_sampling(&mut self) {
        for ((outgoing, roots), sums) in self.outgoing.iter_mut().zip(&mut self.roots).zip(&self.sums) {
            let n = atomic_f32::load(&sums[2]);
            let (mean_outgoing, second_moment) = if n >= MIN_SAMPLES {
                (atomic_f32::load(&sums[0]) / n, atomic_f32::load(&sums[1]) / n)
            } else {
                (-1.0, -1.0)
            };
            let went_on = atomic_f32::load(&sums[4]);
            let cost = if went_on > 0.0 { atomic_f32::load(&sums[3]) / went_on } else { 0.0 };
            *outgoing = mean_outgoing;
            *roots = if second_moment < 0.0 {
                [-1.0, -1.0]
            } else if cost > 0.0 {
                [libm::sqrtf(second_moment), libm::sqrtf(second_moment / cost)]
            } else {
                [libm::sqrtf(second_moment), -1.0]
            };
        }
    }

    /// Cell sides whose means decide (since the last rebuild).
    pub fn cells_known(&self) -> usize {
        self.outgoing.iter().filter(|&&o| o >= 0.0).count()
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.sums.len() * (SUMS * 4 + 3 * 4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roulette() -> EfficiencyRoulette {
        EfficiencyRoulette::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0), 2).unwrap()
    }

    const IMAGE: RouletteImage = RouletteImage { pixel: 2.0, relative_variance: 1.0, path_cost: 0.0 };

    #[test]
    fn nothing_decides_before_enough_samples_are_learned_and_rebuilt() {
        let mut roulette = roulette();
        let cell = roulette.locate(Vec3::splat(0.5), Vec3::Y).unwrap();
        for _ in 0..15 {
            roulette.record(cell, 2.0, 1.0, None);
        }
        roulette.rebuild_sampling();
        assert_eq!(roulette.pixel_estimate(cell, 0.0), None);
        let scale = IMAGE.scale().unwrap();
        assert_eq!(roulette.continuations(cell, 1.0, scale), None);
        roulette.record(cell, 2.0, 1.0, None);
        assert_eq!(roulette.continuations(cell, 1.0, scale), None, "learning alone changes nothing");
        roulette.rebuild_sampling();
        assert_eq!(roulette.pixel_estimate(cell, 0.5), Some(2.5));
        assert_eq!(roulette.cells_known(), 1);
    }

    #[test]
    fn continuations_follow_the_root_of_the_second_moment_and_the_cost_ratio() {
        let mut roulette = roulette();
        let cell = roulette.locate(Vec3::splat(0.5), Vec3::Y).unwrap();
        // Continuations of 0 and 2 in turn: mean 1, second moment 2.
        for i in 0..20 {
            roulette.record(cell, 4.0, if i % 2 == 0 { 0.0 } else { 2.0 }, Some(2.0));
        }
        roulette.rebuild_sampling();
        let q = |throughput: f32, image: RouletteImage| roulette.continuations(cell, throughput, image.scale()?);
        let expected = 0.5 * 2f32.sqrt() / 2.0;
        assert!((q(0.5, IMAGE).unwrap() - expected).abs() < 1e-6);
        // A path costing 4× what going on from here costs: twice the continuations.
        let costly = RouletteImage { path_cost: 8.0, ..IMAGE };
        assert!((q(0.5, costly).unwrap() - 2.0 * expected).abs() < 1e-6);
        assert_eq!(q(2.0, IMAGE), Some(2.0 * 2f32.sqrt() / 2.0));
        assert_eq!(q(100.0, IMAGE), Some(MAX_SPLIT));
        assert_eq!(q(1e-6, IMAGE), Some(MIN_SURVIVAL));
        assert_eq!(q(1.0, RouletteImage { pixel: 0.0, ..IMAGE }), None);
        assert_eq!(q(1.0, RouletteImage { relative_variance: 0.0, ..IMAGE }), None);
        assert_eq!(q(f32::NAN, IMAGE), None);
    }

    #[test]
    fn the_two_faces_of_a_wall_learn_apart_and_bad_samples_are_left_out() {
        let mut roulette = roulette();
        let lit = roulette.locate(Vec3::splat(0.5), Vec3::X).unwrap();
        let dark = roulette.locate(Vec3::splat(0.5), -Vec3::X).unwrap();
        assert_ne!(lit, dark);
        for _ in 0..20 {
            roulette.record(lit, 8.0, 4.0, None);
            roulette.record(dark, 0.5, 0.5, None);
            roulette.record(dark, f32::NAN, 1.0, None);
            roulette.record(dark, -1.0, 1.0, None);
            roulette.record(dark, 0.5, f32::INFINITY, None);
        }
        roulette.rebuild_sampling();
        assert_eq!(roulette.pixel_estimate(lit, 0.0), Some(8.0));
        assert_eq!(roulette.pixel_estimate(dark, 0.0), Some(0.5));
        assert_eq!(roulette.locate(Vec3::NAN, Vec3::X), None);
        assert_eq!(roulette.locate(Vec3::ONE, Vec3::NAN), None);
    }

    #[test]
    fn settings_out_of_range_are_named() {
        let err = EfficiencyRoulette::new(Vec3::ZERO, Vec3::ONE, 0).unwrap_err();
        assert!(alloc::format!("{err}").contains("roulette_resolution"));
        let err = EfficiencyRoulette::new(Vec3::ONE, Vec3::ZERO, 8).unwrap_err();
        assert!(alloc::format!("{err}").contains("bounds"));
    }
}
