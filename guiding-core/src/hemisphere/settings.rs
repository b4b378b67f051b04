//! Configuration of a [`HemisphereGrid`](super::HemisphereGrid) and its memory sizing.

use crate::error::{require, Error};
use crate::update_rule::UpdateRule;

use super::mapping::PatchLayout;

/// Default memory budget: 2 MiB, the patent's example.
pub const DEFAULT_BUDGET_BYTES: usize = 2 << 20;

/// The most probes one grid holds (2²⁴): probe indices and counts stay exact in f32.
pub const MAX_PROBES: usize = 1 << 24;

/// Everything that shapes a hemisphere grid and how it learns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HemisphereGridSettings {
    /// Memory budget for all tables, bytes. Sets the probe count unless `probe_count` does.
    pub budget_bytes: usize,
    /// An exact probe count, which must fit the budget; `None` fills the budget.
    pub probe_count: Option<usize>,
    /// How each hemisphere is cut into patches.
    pub layout: PatchLayout,
    /// Place each probe point twice, once per side of its surface (two-sided surfaces
    /// seen from both sides); otherwise only the front side (the winding's normal).
    pub two_sided: bool,
    /// A hit uses the nearest probe whose normal is within this angle of its own, degrees,
    /// in (0, 180].
    pub max_normal_angle_deg: f32,
    /// How many shells of lookup cells around a hit are searched for a probe, in 1..=16:
    /// a hit finds probes within `max_search_rings` cells (each about one probe spacing).
    pub max_search_rings: u32,
    /// Q of every patch before learning: radiance, ≥ `q_floor`. An optimistic value makes
    /// unvisited directions attractive early on.
    pub initial_q: f32,
    /// Lower bound of every stored Q (radiance, > 0), so no patch ever reaches zero.
    pub q_floor: f32,
    /// Share of each probe's sampling probability spread uniformly over its patches, in
    /// [0, 1]: keeps every patch at least `uniform_mix / patches` likely.
    pub uniform_mix: f32,
    /// Exponent γ in (0, 1] of the sampling weights Q^γ: 1 samples ∝ Q (the paper);
    /// smaller values temper a peaked Q towards uniform, so directions Q has not (yet)
    /// learned to be bright are not starved.
    pub sampling_exponent: f32,
    /// Sample patch k in proportion to Q_k·∫_k cos θ dω rather than Q_k: the product of
    /// the incident radiance with a Lambertian surface's cosine, free here because a
    /// probe's normal is fixed. The pdf stays uniform inside each patch.
    pub cosine_product: bool,
    /// Learning rate and integral estimator.
    pub update_rule: UpdateRule,
}

impl Default for HemisphereGridSettings {
    fn default() -> Self {
        Self {
            budget_bytes: DEFAULT_BUDGET_BYTES,
            probe_count: None,
            layout: PatchLayout::default(),
            two_sided: false,
            max_normal_angle_deg: 45.0,
            max_search_rings: 2,
            initial_q: 1e-2,
            q_floor: f32::MIN_POSITIVE,
            uniform_mix: 0.02,
            sampling_exponent: 1.0,
            cosine_product: false,
            update_rule: UpdateRule::default(),
        }
    }
}

impl HemisphereGridSettings {
    /// Checks every setting's range.
    pub fn validate(&self) -> Result<(), Error> {
        self.layout.validate()?;
        self.update_rule.validate()?;
        let check = require;
        check(self.budget_bytes > 0, "budget_bytes", self.budget_bytes as f64, "positive")?;
        if let Some(count) = self.probe_count {
            check(count >= 1, "probe_count", count as f64, "at least 1")?;
            check(count <= MAX_PROBES, "probe_count", count as f64, "at most 2^24")?;
        }
        let angle = self.max_normal_angle_deg;
        check(angle > 0.0 && angle <= 180.0, "max_normal_angle_deg", angle as f64, "in (0, 180]")?;
        let rings = self.max_search_rings;
        check((1..=16).contains(&rings), "max_search_rings", rings as f64, "in 1..=16")?;
        let floor = self.q_floor;
        check(floor > 0.0 && floor.is_finite(), "q_floor", floor as f64, "positive and finite")?;
        let initial = self.initial_q;
        check(initial >= floor && initial.is_finite(), "initial_q", initial as f64, "finite and at least q_floor")?;
        let mix = self.uniform_mix;
        check((0.0..=1.0).contains(&mix), "uniform_mix", mix as f64, "in [0, 1]")?;
        let exponent = self.sampling_exponent;
        check(exponent > 0.0 && exponent <= 1.0, "sampling_exponent", exponent as f64, "in (0, 1]")
    }

    /// Bytes of all tables of a grid with `probes` probes (see
    /// [`HemisphereGrid::memory_bytes`](super::HemisphereGrid::memory_bytes)).
    pub fn memory_bytes(&self, probes: usize) -> usize {
        super::grid::table_bytes(probes, self.layout.patch_count())
    }

    /// The probe count: `probe_count` if set and within budget, else the most probes the
    /// budget holds. Errors when not even one probe fits.
    pub fn resolve_probe_count(&self) -> Result<usize, Error> {
        self.validate()?;
        if let Some(count) = self.probe_count {
            let needed = self.memory_bytes(count);
            if needed > self.budget_bytes {
                return Err(Error::OverBudget {
                    regions: count,
                    needed_bytes: needed,
                    budget_bytes: self.budget_bytes,
                });
            }
            return Ok(count);
        }
        if self.memory_bytes(1) > self.budget_bytes {
            return Err(Error::BudgetTooSmall { budget_bytes: self.budget_bytes, needed_bytes: self.memory_bytes(1) });
        }
        // Memory grows monotonically with the count: binary search the largest that fits.
        let (mut fits, mut too_many) = (1usize, MAX_PROBES + 1);
        while too_many - fits > 1 {
            let middle = fits + (too_many - fits) / 2;
            if self.memory_bytes(middle) <= self.budget_bytes {
                fits = middle;
            } else {
                too_many = middle;
            }
        }
        Ok(fits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemisphere::mapping::{HemisphereMapping, PatchLayout};

    #[test]
    fn default_budget_is_filled_but_not_exceeded() {
        let settings = HemisphereGridSettings::default();
        let probes = settings.resolve_probe_count().unwrap();
        assert!(settings.memory_bytes(probes) <= DEFAULT_BUDGET_BYTES);
        assert!(settings.memory_bytes(probes + 1) > DEFAULT_BUDGET_BYTES);
        assert!(probes > 900, "{probes}");
    }

    #[test]
    fn tiny_budgets_and_huge_counts_are_errors() {
        let tiny = HemisphereGridSettings { budget_bytes: 100, ..Default::default() };
        assert!(matches!(tiny.resolve_probe_count(), Err(Error::BudgetTooSmall { budget_bytes: 100, .. })));
        let over = HemisphereGridSettings { probe_count: Some(1_000_000), ..Default::default() };
        assert!(matches!(over.resolve_probe_count(), Err(Error::OverBudget { regions: 1_000_000, .. })));
        let one = HemisphereGridSettings { probe_count: Some(1), ..Default::default() };
        assert_eq!(one.resolve_probe_count(), Ok(1));
        let huge = HemisphereGridSettings {
            layout: PatchLayout { mapping: HemisphereMapping::Cylindrical, resolution: [1024, 1024] },
            ..Default::default()
        };
        assert!(matches!(huge.resolve_probe_count(), Err(Error::ResolutionTooLarge { .. })));
    }

    #[test]
    fn invalid_values_name_the_setting() {
        let cases: [(HemisphereGridSettings, &str); 6] = [
            (HemisphereGridSettings { q_floor: 0.0, ..Default::default() }, "q_floor"),
            (HemisphereGridSettings { initial_q: f32::NAN, ..Default::default() }, "initial_q"),
            (HemisphereGridSettings { uniform_mix: 1.5, ..Default::default() }, "uniform_mix"),
            (HemisphereGridSettings { max_normal_angle_deg: 0.0, ..Default::default() }, "max_normal_angle_deg"),
            (HemisphereGridSettings { probe_count: Some(0), ..Default::default() }, "probe_count"),
            (HemisphereGridSettings { budget_bytes: 0, ..Default::default() }, "budget_bytes"),
        ];
        for (settings, expected) in cases {
            match settings.validate() {
                Err(Error::InvalidSetting { name, .. }) => assert_eq!(name, expected),
                other => panic!("{expected}: {other:?}"),
            }
        }
    }
}
