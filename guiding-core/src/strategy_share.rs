//! How much of a one-sample mixture one sampling strategy (the focal boxes, a directional
//! guide) should get, learned per cell of a coarse grid over the scene.
//!
//! A vertex that scatters by the mixture p = s·g + (1 − s − r)·b + r·o (the strategy g at
//! share s, the BSDF b, any other strategies o at their shares r) records what arrived
//! along the direction it drew. For each candidate share c, the second moment ∫ F²/p_c of
//! the estimator with that share is estimated from the direction drawn with p as
//! F²/(p·p_c), where p_c = p + (c − s)·(g − b), and the variance from it less the squared
//! mean F/p. Each cell picks the candidate with the least variance times cost, a share
//! above 0 costing `1 + cost` (the strategy's lookups at every vertex of the cell); where
//! a strategy does not pay that is 0, and the renderer skips its calls.

use alloc::vec::Vec;
use core::sync::atomic::AtomicU32;

use glam::Vec3;

use crate::atomic_f32;
use crate::coarse_grid::CoarseGrid;
use crate::error::{require, Error};
use crate::update_rule::{classify_target, UpdateOutcome};

/// The shares each cell weighs ([`StrategyShares::CANDIDATES`]).
pub(crate) const CANDIDATES: [f32; 7] = [0.0, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5];

/// Arrivals a cell needs before it picks a share above 0.
const MIN_ARRIVALS: f32 = 64.0;

/// One direction a vertex scattered into, as the shares learn from it: what arrived and
/// every density that drew it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrategyArrival {
    /// The vertex, world space.
    pub point: Vec3,
    /// fs·cos θ × the radiance that arrived along the direction (luminance): the
    /// integrand of the vertex's scattering integral there.
    pub integrand: f32,
    /// The pdf the direction was drawn with (the whole mixture's), per steradian.
    pub pdf: f32,
    /// The strategy's pdf of the direction.
    pub strategy_pdf: f32,
    /// The BSDF's own pdf of it.
    pub bsdf_pdf: f32,
    /// The strategy's share in the mixture that drew it; the BSDF's share changes with
    /// it, every other strategy's stays.
    pub selection: f32,
}

/// Per cell of a grid over a box, the learned share of one strategy.
#[derive(Debug)]
pub struct StrategyShares {
    grid: CoarseGrid,
    /// Per cell the estimated second moment at each candidate (Σ F²/(p·p_c)) and the arrivals counted
    /// (f32 bits, learning), and the share chosen at the last rebuild (sampling).
    moments: Vec<[AtomicU32; CANDIDATES.len()]>,
    /// Per cell Σ F/p (f32 bits, learning): the arrivals' estimate of the integral.
    means: Vec<AtomicU32>,
    arrivals: Vec<AtomicU32>,
    /// The relative cost of a vertex that uses the strategy (its lookups) against one
    /// that does not; 0 weighs variance alone.
    cost: f32,
    shares: Vec<f32>,
    /// Whether some cell's share is above 0 (since the last rebuild).
    any: bool,
}

impl StrategyShares {
    /// The shares each cell weighs.
    pub const CANDIDATES: [f32; 7] = CANDIDATES;

    /// Cells over `low..high`, `resolution` (1..=64) along the longest side and the other
    /// sides in proportion; every share 0 until learned.
    pub fn new(low: Vec3, high: Vec3, resolution: u32) -> Result<Self, Error> {
        require((1..=64).contains(&resolution), "share_resolution", resolution as f64, "in 1..=64")?;
        let grid = CoarseGrid::new(low, high, resolution)?;
        let count = grid.len();
        Ok(Self {
            grid,
            moments: (0..count).map(|_| core::array::from_fn(|_| atomic_f32::new(0.0))).collect(),
            means: (0..count).map(|_| atomic_f32::new(0.0)).collect(),
            cost: 0.0,
            arrivals: (0..count).map(|_| atomic_f32::new(0.0)).collect(),
            shares: alloc::vec![0.0; count],
            any: false,
        })
    }

    /// The same grid, where a share above 0 must lower the variance by more than the
    /// relative cost `cost` (≥ 0, finite) of the strategy's lookups to be chosen:
    /// variance × (1 + cost) against the variance at share 0.
    pub fn with_cost(mut self, cost: f32) -> Result<Self, Error> {
        require(cost.is_finite() && cost >= 0.0, "share_cost", cost as f64, "finite and at least 0")?;
        self.cost = cost;
        Ok(self)
    }

    /// The cell holding `point` (clamped into the grid).
    #[inline]
    pub(crate) fn cell(&self, point: Vec3) -> Option<usize> {
        self.grid.cell(point)
    }

    /// The share the strategy should get at `point`: of the
    /// [`CANDIDATES`](Self::CANDIDATES), the one whose estimator had the least variance
    /// (times `1 + cost` above 0) over the arrivals learned around it (0 before enough
    /// were).
    #[inline]
    pub fn share(&self, point: Vec3) -> f32 {
        self.cell(point).map_or(0.0, |cell| self.shares[cell])
    }

    /// Whether some cell gives the strategy a share above 0: where none does, a renderer
    /// that is not learning can leave the strategy out without looking anything up.
    #[inline]
    pub fn any(&self) -> bool {
        self.any
    }

    /// Learns how each candidate share would have served the vertex of `arrival`.
    /// Lock-free; safe from many threads during a pass.
    pub fn record(&self, arrival: &StrategyArrival) -> UpdateOutcome {
        let integrand = match classify_target(arrival.integrand) {
            Ok(f) => f,
            Err(outcome) => return outcome,
        };
        let densities = [arrival.pdf, arrival.strategy_pdf, arrival.bsdf_pdf, arrival.selection];
        if !densities.iter().all(|d| d.is_finite() && *d >= 0.0) || arrival.pdf <= 0.0 {
            return UpdateOutcome::OutsideDomain;
        }
        let Some(cell) = self.cell(arrival.point) else { return UpdateOutcome::OutsideDomain };
        atomic_f32::update(&self.arrivals[cell], |n| n + 1.0);
        if integrand > 0.0 {
            let ratio = integrand as f64 / arrival.pdf as f64;
            atomic_f32::update(&self.means[cell], |m| (m + ratio.min(f32::MAX as f64) as f32).min(f32::MAX));
            let square = integrand as f64 * ratio;
            for (moment, &c) in self.moments[cell].iter().zip(&CANDIDATES) {
                let mixture = arrival.pdf as f64
                    + (c - arrival.selection) as f64 * (arrival.strategy_pdf as f64 - arrival.bsdf_pdf as f64);
                // A share whose mixture could not have drawn this direction would miss what
                // arrived along it: its estimator is biased, its moment infinite.
                let term = if mixture > 0.0 { (square / mixture).min(f32::MAX as f64) as f32 } else { f32::MAX };
                atomic_f32::update(moment, |m| (m + term).min(f32::MAX));
            }
        }
        UpdateOutcome::Accepted
    }

    /// Picks each cell's share from what it learned. The moments were measured against
    /// the strategy of their time: older ones fade by half at every rebuild.
    pub fn rebuild_sampling(&mut self) {
        let cells = self.shares.iter_mut().zip(&self.moments).zip(&self.means).zip(&self.arrivals);
        for (((share, moments), mean), arrivals) in cells {
            let seen = atomic_f32::load(arrivals);
            // Variance = second moment − mean², per arrival; the mean is the same for
            // every candidate (each estimates the same integral).
            let n = seen.max(1.0) as f64;
            let mean_per_arrival = atomic_f32::load(mean) as f64 / n;
            let mean_square = mean_per_arrival * mean_per_arrival;
            let best = moments
                .iter()
                .zip(CANDIDATES)
                .map(|(m, c)| {
                    let variance = (atomic_f32::load(m) as f64 / n - mean_square).max(0.0);
                    let cost = if c > 0.0 { 1.0 + self.cost as f64 } else { 1.0 };
                    (variance * cost, c)
                })
                .fold((f64::INFINITY, 0.0), |best, (v, c)| if v < best.0 { (v, c) } else { best });
            // Σ F/p grows only with arrivals that brought light.
            let any_light = atomic_f32::load(mean) > 0.0;
            *share = if seen >= MIN_ARRIVALS && any_light { best.1 } else { 0.0 };
            for m in moments.iter().chain([mean]) {
                atomic_f32::update(m, |m| 0.5 * m);
            }
            atomic_f32::update(arrivals, |n| 0.5 * n);
        }
        self.any = self.shares.iter().any(|&s| s > 0.0);
    }

    /// Cells whose share is above 0 (since the last rebuild).
    pub fn cells_in_use(&self) -> usize {
        self.shares.iter().filter(|&&s| s > 0.0).count()
    }

    /// Cells in the grid.
    pub fn cell_count(&self) -> usize {
        self.shares.len()
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.shares.len() * ((CANDIDATES.len() + 2) * 4 + 4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Arrivals at one point whose integrand the strategy's density matches (F = g): the
    /// strategy should get the most; where it is blind to F (g = 0 where F > 0 and
    /// F = b), none.
    #[test]
    fn a_strategy_that_matches_the_integrand_gets_the_largest_share_and_a_blind_one_none() {
        let mut shares = StrategyShares::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0), 2).unwrap();
        let (good, blind) = (Vec3::new(0.5, 0.5, 0.5), Vec3::new(1.5, 0.5, 0.5));
        let mut rng = crate::Pcg32::new(3, 3);
        for _ in 0..4000 {
            // Drawn by the BSDF alone (share 0): b = 1/(2π) uniform, the strategy
            // concentrated where F is (g = 10·b on a tenth of the directions).
            let inside = rng.next_f32() < 0.1;
            let b = 0.5 / core::f32::consts::PI;
            let g = if inside { 10.0 * b } else { 0.0 };
            let f = if inside { 1.0 } else { 0.0 };
            let arrival =
                StrategyArrival { point: good, integrand: f, pdf: b, strategy_pdf: g, bsdf_pdf: b, selection: 0.0 };
            assert_eq!(shares.record(&arrival), UpdateOutcome::Accepted);
            // Blind: F everywhere, the strategy nowhere.
            let arrival = StrategyArrival {
                point: blind,
                integrand: 1.0,
                pdf: b,
                strategy_pdf: 0.0,
                bsdf_pdf: b,
                selection: 0.0,
            };
            shares.record(&arrival);
        }
        assert!(!shares.any(), "nothing before the first rebuild");
        shares.rebuild_sampling();
        assert_eq!(shares.share(good), *CANDIDATES.last().unwrap());
        assert_eq!(shares.share(blind), 0.0);
        assert!(shares.any());
        // Bad input is refused, not learned.
        let bad = StrategyArrival {
            point: good,
            integrand: f32::NAN,
            pdf: 1.0,
            strategy_pdf: 1.0,
            bsdf_pdf: 1.0,
            selection: 0.0,
        };
        assert_eq!(shares.record(&bad), UpdateOutcome::RejectedNonFinite);
        let bad = StrategyArrival { pdf: 0.0, integrand: 1.0, ..bad };
        assert_eq!(shares.record(&bad), UpdateOutcome::OutsideDomain);
        assert!(StrategyShares::new(Vec3::ZERO, Vec3::ONE, 0).is_err());
        assert!(StrategyShares::new(Vec3::ONE, Vec3::ZERO, 4).is_err());
    }

    /// Learns two cells from directions drawn by a uniform BSDF (share 0): in `good` the
    /// strategy matches an integrand concentrated on a tenth of the directions (variance
    /// at share 0.5 about 0.09 of that at 0), in `mild` it leans a little towards the
    /// brighter half (about 0.49).
    fn learn_good_and_mild(shares: &mut StrategyShares, good: Vec3, mild: Vec3) {
        let b = 0.5 / core::f32::consts::PI;
        let mut rng = crate::Pcg32::new(5, 9);
        for _ in 0..8000 {
            let inside = rng.next_f32() < 0.1;
            let (f, g) = if inside { (1.0, 10.0 * b) } else { (0.0, 0.0) };
            shares.record(&StrategyArrival {
                point: good,
                integrand: f,
                pdf: b,
                strategy_pdf: g,
                bsdf_pdf: b,
                selection: 0.0,
            });
            let bright = rng.next_f32() < 0.5;
            let (f, g) = if bright { (1.0, 1.2 * b) } else { (0.5, 0.8 * b) };
            shares.record(&StrategyArrival {
                point: mild,
                integrand: f,
                pdf: b,
                strategy_pdf: g,
                bsdf_pdf: b,
                selection: 0.0,
            });
        }
        shares.rebuild_sampling();
    }

    /// A cost keeps the strategy out of the cell whose variance it halves (0.49 × 2.5 >
    /// 1) and in the one where it cuts it elevenfold; without a cost both use it.
    #[test]
    fn a_cost_keeps_a_strategy_only_where_it_pays_for_its_lookups() {
        let (low, high) = (Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0));
        let (good, mild) = (Vec3::new(0.5, 0.5, 0.5), Vec3::new(1.5, 0.5, 0.5));
        let mut free = StrategyShares::new(low, high, 2).unwrap();
        learn_good_and_mild(&mut free, good, mild);
        assert_eq!(free.share(good), 0.5);
        assert!(free.share(mild) >= 0.2, "{}", free.share(mild));
        assert_eq!(free.cells_in_use(), 2);
        let mut costly = StrategyShares::new(low, high, 2).unwrap().with_cost(1.5).unwrap();
        learn_good_and_mild(&mut costly, good, mild);
        assert_eq!(costly.share(good), 0.5);
        assert_eq!(costly.share(mild), 0.0);
        assert_eq!(costly.cells_in_use(), 1);
        for bad in [-0.1, f32::NAN, f32::INFINITY] {
            let error = StrategyShares::new(low, high, 2).unwrap().with_cost(bad).unwrap_err();
            assert!(matches!(error, Error::InvalidSetting { name: "share_cost", .. }), "{error:?}");
        }
    }
}
