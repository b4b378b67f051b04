//! [`NextEventGate`]: per grid cell, the probability of shooting a next-event shadow ray
//! at all, learned from the share of shadow rays that arrived there.

use core::sync::atomic::{AtomicU32, Ordering};

use alloc::vec;
use alloc::vec::Vec;
use glam::Vec3;

use crate::atomic_f32;
use crate::cell_grid::CellGrid;
use crate::error::{require, Error};

/// Shadow rays a cell needs before its gate closes below 1.
const GATE_MIN_SHOTS: u32 = 64;

/// Bytes per cell: shadow rays shot and arrived, the probability.
const CELL_BYTES: usize = 12;

/// A cell of a [`NextEventGate`]'s grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct GateCell(pub u32);

/// Everything that shapes a next-event gate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NextEventGateSettings {
    /// Memory budget for the per-cell tables, bytes; sets the grid resolution unless
    /// `resolution` does.
    pub budget_bytes: usize,
    /// Cells along x, y, z; `None` fills the budget with near-cubic cells.
    pub resolution: Option<[u32; 3]>,
    /// The scale, > 0: a cell whose share of arriving shadow rays is v estimates
    /// next-event light with probability clamp(scale · v, floor, 1).
    pub scale: f32,
    /// The least probability of a shadow ray, in (0, 1].
    pub floor: f32,
}

impl Default for NextEventGateSettings {
    fn default() -> Self {
        Self { budget_bytes: 256 << 10, resolution: None, scale: 20.0, floor: 0.1 }
    }
}

impl NextEventGateSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        require(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        crate::cell_grid::validate_resolution(self.resolution)?;
        let scale = self.scale;
        require(scale.is_finite() && scale > 0.0, "gate_scale", scale as f64, "finite and > 0")?;
        let floor = self.floor;
        require(floor > 0.0 && floor <= 1.0, "gate_floor", floor as f64, "in (0, 1]")
    }
}

/// Where a light is hidden from nearly everywhere (behind a door), most next-event shadow
/// rays are wasted. The gate learns, per cell of a regular grid over the scene, the share
/// v of shadow rays that arrived, and gives next-event estimation the probability
/// clamp(scale · v, floor, 1) there. A vertex whose shadow ray the gate skips leaves its
/// light to the scattered direction: emission found by scattering is weighed by MIS
/// against that probability times the light pdf, so the image stays unbiased.
///
/// ```
/// use guiding_core::{NextEventGate, NextEventGateSettings};
/// use glam::Vec3;
///
/// let mut gate = NextEventGate::new(Vec3::ZERO, Vec3::ONE, NextEventGateSettings::default())?;
/// let cell = gate.locate(Vec3::splat(0.1)).expect("inside the bounds");
/// for _ in 0..1000 {
///     gate.record(cell, false); // behind the door: nothing arrives
/// }
/// gate.rebuild_sampling();
/// assert_eq!(gate.probability(cell), 0.1); // the floor
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Debug)]
pub struct NextEventGate {
    settings: NextEventGateSettings,
    grid: CellGrid,
    shots: Vec<AtomicU32>,
    arrivals: Vec<AtomicU32>,
    probability: Vec<f32>,
}

impl NextEventGate {
    /// A gate over the box `low..high` (scene units), open (probability 1) everywhere
    /// until it has learned.
    pub fn new(low: Vec3, high: Vec3, settings: NextEventGateSettings) -> Result<Self, Error> {
        settings.validate()?;
        let grid = CellGrid::new(low, high, settings.resolution, settings.budget_bytes, CELL_BYTES)?;
        let cells = grid.cell_count();
        Ok(Self {
            settings,
            grid,
            shots: (0..cells).map(|_| AtomicU32::new(0)).collect(),
            arrivals: (0..cells).map(|_| AtomicU32::new(0)).collect(),
            probability: vec![1.0; cells],
        })
    }

    /// The cell holding `position`; points outside the bounds use the nearest cell.
    /// `None` for a non-finite position.
    #[inline]
    pub fn locate(&self, position: Vec3) -> Option<GateCell> {
        self.grid.cell(position).map(GateCell)
    }

    /// The probability with which a vertex in `cell` estimates next-event light (1 before
    /// the cell has seen enough shadow rays, and for a cell not of this grid).
    #[inline]
    pub fn probability(&self, cell: GateCell) -> f32 {
        self.probability.get(cell.0 as usize).copied().unwrap_or(1.0)
    }

    /// Counts one shadow ray shot from `cell`, and whether it arrived. Lock-free; safe
    /// from many threads during a pass.
    pub fn record(&self, cell: GateCell, arrived: bool) {
        let Some(shots) = self.shots.get(cell.0 as usize) else { return };
        atomic_f32::increment_saturating(shots);
        if arrived {
            atomic_f32::increment_saturating(&self.arrivals[cell.0 as usize]);
        }
    }

    /// Sets every cell's probability from the shadow rays it counted. Call between passes.
    pub fn rebuild_sampling(&mut self) {
        let NextEventGateSettings { scale, floor, .. } = self.settings;
        for ((probability, shots), arrivals) in self.probability.iter_mut().zip(&self.shots).zip(&self.arrivals) {
            let (shots, arrivals) = (shots.load(Ordering::Relaxed), arrivals.load(Ordering::Relaxed));
            *probability =
                if shots >= GATE_MIN_SHOTS { (scale * arrivals as f32 / shots as f32).clamp(floor, 1.0) } else { 1.0 };
        }
    }

    /// Cells along x, y and z.
    pub fn resolution(&self) -> [u32; 3] {
        self.grid.resolution()
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.grid.cell_count()
    }

    /// Bytes held by the tables.
    pub fn memory_bytes(&self) -> usize {
        self.grid.cell_count() * CELL_BYTES + core::mem::size_of::<Self>()
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &NextEventGateSettings {
        &self.settings
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gate_closes_where_shadow_rays_never_arrive_and_stays_open_elsewhere() {
        let settings = NextEventGateSettings { scale: 5.0, floor: 0.1, ..Default::default() };
        let mut g = NextEventGate::new(Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0), settings).unwrap();
        let (hidden, lit, half, young) = (
            g.locate(Vec3::new(0.1, 0.1, 0.1)).unwrap(),
            g.locate(Vec3::new(3.9, 1.9, 0.9)).unwrap(),
            g.locate(Vec3::new(2.0, 1.0, 0.5)).unwrap(),
            g.locate(Vec3::new(3.9, 0.1, 0.1)).unwrap(),
        );
        for i in 0..1000 {
            g.record(hidden, false);
            g.record(lit, true);
            // One in twenty arrives: 5 × 0.05 = 0.25.
            g.record(half, i % 20 == 0);
        }
        for _ in 0..(GATE_MIN_SHOTS - 1) {
            g.record(young, false);
        }
        for cell in [hidden, lit, half, young] {
            assert_eq!(g.probability(cell), 1.0, "open until the first rebuild");
        }
        g.rebuild_sampling();
        assert_eq!(g.probability(hidden), 0.1, "closed to the floor");
        assert_eq!(g.probability(lit), 1.0);
        assert!((g.probability(half) - 0.25).abs() < 1e-6, "{}", g.probability(half));
        assert_eq!(g.probability(young), 1.0, "too few rays to judge");
        assert_eq!(g.probability(GateCell(u32::MAX)), 1.0);
        g.record(GateCell(u32::MAX), true); // ignored, no panic
        assert_eq!(g.locate(Vec3::NAN), None);
        assert!(g.memory_bytes() <= settings.budget_bytes + core::mem::size_of::<NextEventGate>());
    }

    #[test]
    fn bad_settings_are_named() {
        let bad = |scale, floor| NextEventGateSettings { scale, floor, ..Default::default() };
        for (settings, name) in [
            (bad(f32::NAN, 0.1), "gate_scale"),
            (bad(0.0, 0.1), "gate_scale"),
            (bad(-1.0, 0.1), "gate_scale"),
            (bad(1.0, 0.0), "gate_floor"),
            (bad(1.0, 1.5), "gate_floor"),
        ] {
            match NextEventGate::new(Vec3::ZERO, Vec3::ONE, settings) {
                Err(Error::InvalidSetting { name: named, .. }) => assert_eq!(named, name, "{settings:?}"),
                other => panic!("{settings:?}: {other:?}"),
            }
        }
        let tiny = NextEventGateSettings { budget_bytes: 4, ..Default::default() };
        assert!(matches!(NextEventGate::new(Vec3::ZERO, Vec3::ONE, tiny), Err(Error::BudgetTooSmall { .. })));
    }
}
