//! Configuration of an [`EnvTileGuide`](super::EnvTileGuide).

use crate::cell_grid::validate_resolution;
use crate::error::{require, Error};

/// Everything that shapes an environment-tile guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvTileGuideSettings {
    /// Memory budget for the per-cell tables, bytes; sets the grid resolution unless
    /// `resolution` does. The shared texel CDFs (4 bytes per texel) come on top.
    pub budget_bytes: usize,
    /// Cells along x, y, z; `None` fills the budget with near-cubic cells.
    pub resolution: Option<[u32; 3]>,
    /// Tiles across (u, 2π of azimuth) and down (v, π of elevation) the map.
    pub tiles: [u32; 2],
    /// Share of each cell's lobe probability given in proportion to the lobes' power
    /// (plain luminance importance sampling), in [0, 1].
    pub power_mix: f32,
    /// Share spread uniformly over the lobes with power, in (0, 1]: a floor for lobes
    /// that are dim but not black.
    pub uniform_mix: f32,
}

impl Default for EnvTileGuideSettings {
    fn default() -> Self {
        Self { budget_bytes: 1 << 20, resolution: None, tiles: [32, 16], power_mix: 0.1, uniform_mix: 0.01 }
    }
}

/// Bytes per (cell, lobe) entry: the learned value, its update count and the CDF.
pub(crate) const ENTRY_BYTES: usize = 12;

impl EnvTileGuideSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        require(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        validate_resolution(self.resolution)?;
        for (axis, &n) in self.tiles.iter().enumerate() {
            require((1..=4096).contains(&n), ["tiles.u", "tiles.v"][axis], n as f64, "in 1..=4096")?;
        }
        let (power, uniform) = (self.power_mix, self.uniform_mix);
        require((0.0..=1.0).contains(&power), "power_mix", power as f64, "in [0, 1]")?;
        require(uniform > 0.0 && uniform <= 1.0, "uniform_mix", uniform as f64, "in (0, 1]")?;
        require(power + uniform <= 1.0, "power_mix + uniform_mix", (power + uniform) as f64, "at most 1")
    }
}
