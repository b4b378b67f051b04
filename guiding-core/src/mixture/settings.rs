//! Configuration of a [`GaussianMixture`](super::GaussianMixture) guide and its sizing.

use core::mem::size_of;

use crate::cell_grid::validate_resolution;
use crate::error::{require, Error};
use crate::update_rule::UpdateRule;

use super::vmf_mixture::{VmfMixture, MAX_LOBES};

/// Everything that shapes a mixture guide and how it learns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussianMixtureSettings {
    /// Memory budget for every region's mixture and batch statistics, bytes. Sets the
    /// grid's resolution unless `resolution` does.
    pub budget_bytes: usize,
    /// Cells along x, y and z (each 1..=1024), or `None` to fill the budget with
    /// near-cubic cells.
    pub resolution: Option<[u32; 3]>,
    /// Lobes per mixture, in 1..=[`MAX_LOBES`]. 2 by default: the tracer measured 2
    /// ahead of 3 and 6 on its door and cornell scenes (each lobe costs per sample).
    pub lobes: usize,
    /// Give each cell six regions, one per sign of the normal's largest axis, so the two
    /// sides of a wall inside one cell (or a floor and the wall above it) learn apart.
    pub split_by_normal: bool,
    /// Q per unit solid angle before learning (radiance): the mixture starts uniform
    /// with ∫Q dω = 4π·initial_q. The first batch replaces it under simple averaging.
    pub initial_q: f32,
    /// Share of the sampling density spread uniformly over the sphere, in [0, 1]: keeps
    /// every direction's pdf at least `uniform_mix / 4π` however sharp the lobes get.
    pub uniform_mix: f32,
    /// Learning rate (applied to the batch statistics between passes) and integral
    /// estimator (the mixture always estimates ∫Q fs cos by one sample per lobe).
    pub update_rule: UpdateRule,
}

impl Default for GaussianMixtureSettings {
    fn default() -> Self {
        Self {
            budget_bytes: 2 << 20,
            resolution: None,
            lobes: 2,
            split_by_normal: true,
            initial_q: 1e-2,
            uniform_mix: 0.02,
            update_rule: UpdateRule::default(),
        }
    }
}

impl GaussianMixtureSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        self.update_rule.validate()?;
        validate_resolution(self.resolution)?;
        require(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        require((1..=MAX_LOBES).contains(&self.lobes), "lobes", self.lobes as f64, "in 1..=8")?;
        let q = self.initial_q;
        require(q.is_finite() && q >= 0.0, "initial_q", q as f64, "finite and ≥ 0")?;
        let mix = self.uniform_mix;
        require((0.0..=1.0).contains(&mix), "uniform_mix", mix as f64, "in [0, 1]")?;
        Ok(())
    }

    /// Regions per grid cell: 6 when split by normal, else 1.
    pub fn regions_per_cell(&self) -> usize {
        if self.split_by_normal {
            6
        } else {
            1
        }
    }

    /// Bytes one region holds: its mixture (lobes, weights, statistics) and the batch
    /// accumulators of the current pass (count, Σ r·v and Σ r·v·ω per lobe, 4 bytes each).
    pub fn bytes_per_region(&self) -> usize {
        size_of::<VmfMixture>() + batch_stride(self.lobes) * 4
    }
}

/// 32-bit words of one region's batch accumulators: the sample count, then per lobe
/// Σ r·v and the three components of Σ r·v·ω.
pub(crate) fn batch_stride(lobes: usize) -> usize {
    1 + 4 * lobes
}
