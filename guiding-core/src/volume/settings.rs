//! Configuration of an [`IrradianceVolume`](super::IrradianceVolume) and its sizing.

use crate::cell_grid::validate_resolution;
use crate::error::{require, Error};
use crate::update_rule::UpdateRule;

use super::sphere_layout::SphereLayout;

/// Everything that shapes an irradiance volume and how it learns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IrradianceVolumeSettings {
    /// Memory budget for every leaf's tables and the tree, bytes.
    pub budget_bytes: usize,
    /// Share of the budget the initial grid of leaves takes, in (0, 1]; the rest is
    /// for the leaves that splitting adds where updates concentrate.
    pub initial_share: f32,
    /// The initial grid's cells along x, y and z (each 1..=1024), or `None` to size it
    /// from `initial_share` of the budget.
    pub resolution: Option<[u32; 3]>,
    /// How each leaf's sphere is cut into patches.
    pub layout: SphereLayout,
    /// A leaf whose updates since it was made reach this many per patch splits into
    /// eight (at the next `rebuild_sampling`, most-updated first, while the budget
    /// lasts), > 0.
    pub split_updates_per_patch: f32,
    /// Q of every patch before learning: radiance, ≥ `q_floor`.
    pub initial_q: f32,
    /// Lower bound of every stored Q (radiance, > 0).
    pub q_floor: f32,
    /// Share of each leaf's sampling probability spread uniformly over its patches, in
    /// [0, 1].
    pub uniform_mix: f32,
    /// Learning rate and integral estimator.
    pub update_rule: UpdateRule,
}

impl Default for IrradianceVolumeSettings {
    fn default() -> Self {
        Self {
            budget_bytes: 2 << 20,
            initial_share: 0.25,
            resolution: None,
            layout: SphereLayout::default(),
            split_updates_per_patch: 8.0,
            initial_q: 1e-2,
            q_floor: f32::MIN_POSITIVE,
            uniform_mix: 0.02,
            update_rule: UpdateRule::default(),
        }
    }
}

impl IrradianceVolumeSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        self.layout.validate()?;
        self.update_rule.validate()?;
        validate_resolution(self.resolution)?;
        let check = require;
        check(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        let share = self.initial_share;
        check(share > 0.0 && share <= 1.0, "initial_share", share as f64, "in (0, 1]")?;
        let split = self.split_updates_per_patch;
        check(split.is_finite() && split > 0.0, "split_updates_per_patch", split as f64, "finite and > 0")?;
        let floor = self.q_floor;
        check(floor.is_finite() && floor > 0.0, "q_floor", floor as f64, "finite and > 0")?;
        let q = self.initial_q;
        check(q.is_finite() && q >= floor, "initial_q", q as f64, "finite and ≥ q_floor")?;
        let mix = self.uniform_mix;
        check((0.0..=1.0).contains(&mix), "uniform_mix", mix as f64, "in [0, 1]")
    }

    /// Bytes one leaf holds: per patch Q, visit count, weight sum and CDF (4 bytes each), plus its
    /// leaf visit count, the count at its last CDF build and its nine spherical-harmonic
    /// coefficients.
    pub fn bytes_per_leaf(&self) -> usize {
        self.layout.patch_count() * 16 + 8 + 36
    }

    /// Bytes shared by all leaves: per patch its centre and its nine basis integrals.
    pub fn shared_bytes(&self) -> usize {
        self.layout.patch_count() * (12 + 36)
    }
}

/// Bytes of one tree node (its first child, or its leaf).
pub(crate) const BYTES_PER_NODE: usize = 4;
