//! Configuration of a [`LightGuide`](super::LightGuide).

use crate::cell_grid::validate_resolution;
use crate::error::{require, Error};

/// How V(c, l) learns from next-event shadow rays.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum LightUpdateRule {
    /// The seed's Eq. (3): every unoccluded shadow ray blends ‖C‖∞ (its unshadowed
    /// contribution) into V with α = 1/(1+n), n the number of such updates; occluded rays
    /// leave V alone.
    UnoccludedAverage,
    /// Eq. (3) with occluded shadow rays blended in as zero contributions: V becomes the
    /// mean contribution including visibility, so lights hidden from a cell fade.
    MeanContribution,
    /// The seed's alternative: V = (unoccluded shadow rays + 1) / (shadow rays + 2), the
    /// light's visibility from the cell, times its power share.
    VisibilityRatio,
}

/// Everything that shapes a light guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightGuideSettings {
    /// Memory budget for the per-cell tables, bytes; sets the grid resolution unless
    /// `resolution` does.
    pub budget_bytes: usize,
    /// Cells along x, y, z; `None` fills the budget with near-cubic cells.
    pub resolution: Option<[u32; 3]>,
    /// Share of each cell's selection probability given in proportion to light power,
    /// in [0, 1].
    pub power_mix: f32,
    /// Share spread uniformly over all lights, in (0, 1]: the floor that keeps every
    /// light selectable.
    pub uniform_mix: f32,
    /// How V learns.
    pub rule: LightUpdateRule,
}

impl Default for LightGuideSettings {
    fn default() -> Self {
        Self {
            budget_bytes: 1 << 20,
            resolution: None,
            power_mix: 0.2,
            uniform_mix: 0.01,
            rule: LightUpdateRule::MeanContribution,
        }
    }
}

/// The most lights a guide selects among: quantised probabilities (2⁻²⁴) then still give
/// each light of the uniform share at least one quantum.
pub const MAX_LIGHTS: usize = 1 << 20;

/// Bytes per (cell, light) entry: V, its update count, the shadow-ray count and the CDF.
pub(crate) const ENTRY_BYTES: usize = 16;

impl LightGuideSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        let check = require;
        check(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        validate_resolution(self.resolution)?;
        let power = self.power_mix;
        check((0.0..=1.0).contains(&power), "power_mix", power as f64, "in [0, 1]")?;
        let uniform = self.uniform_mix;
        check(uniform > 0.0 && uniform <= 1.0, "uniform_mix", uniform as f64, "in (0, 1]")?;
        check(power + uniform <= 1.0, "power_mix + uniform_mix", (power + uniform) as f64, "at most 1")
    }
}
