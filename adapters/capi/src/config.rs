//! The creation-time configuration: which structure, its resolution, budget and update rule.

use guiding_core::{
    HemisphereGridSettings, HemisphereMapping, IntegralEstimator, LearningRate, PatchLayout, UpdateRule,
};

use crate::arguments::{check_struct_size, finite, Output};
use crate::status::{guarded, Failure, LodestarStatus};

/// Which Q structure a guide is (`LodestarGuideConfig.structure`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarStructure {
    /// Probes on the surfaces, each with a hemisphere of equal-area patches
    /// (`lodestar_guide_create`).
    HemisphereGrid = 1,
    /// Full-sphere tables at the leaves of an adaptive octree over the scene bounds
    /// (`lodestar_guide_create_volume`).
    IrradianceVolume = 2,
    /// A von Mises–Fisher mixture per cell of a grid over the scene bounds
    /// (`lodestar_guide_create_mixture`).
    GaussianMixture = 3,
    /// A spatial binary tree whose leaves hold directional quadtrees
    /// (`lodestar_guide_create_tree`).
    SpatialDirectionalTree = 4,
}

/// How a hemisphere is cut into equal-area patches (`LodestarGuideConfig.mapping`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarMapping {
    /// Bands in cos θ cut into wedges in φ (Lambert's cylindrical projection).
    Cylindrical = 0,
    /// Shirley–Chiu concentric square, lifted by the equal-area map z = 1 − r².
    ConcentricSquare = 1,
}

/// The learning rate α of Eq. (1) (`LodestarGuideConfig.learning_rate`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarLearningRate {
    /// α = 1/(1 + visits(x, ω)), Eq. (2): the simple average of all targets.
    SimpleAverage = 0,
    /// α = 1/(1 + visits(x)), counted per region.
    RegionVisits = 1,
    /// A constant α = `learning_rate_parameter`, in [0, 1].
    Exponential = 2,
    /// α = (1 + epoch)^(−`learning_rate_parameter`), exponent in [0, 4].
    Global = 3,
}

/// How the integral of Eq. (1) is estimated (`LodestarGuideConfig.integral_estimator`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarIntegralEstimator {
    /// Σ Q_j · ∫_j fs cos dω: exact for Lambertian BSDFs, centre rule otherwise.
    BsdfWeightedSum = 0,
    /// One jittered direction per patch, unbiased for piecewise-constant Q.
    StratifiedPatches = 1,
    /// π · max_j Q_j fs cos θ_j (Q-learning's best action), for comparison.
    MaxEntry = 2,
    /// Lambertian: as `BsdfWeightedSum`; other BSDFs: one direction drawn from the BSDF.
    /// A C callback cannot sample, so through this API it equals `BsdfWeightedSum`.
    BsdfSampled = 3,
    /// No estimate: the caller carries the path's own continuation back as the target
    /// (what Practical Path Guiding records); asked for one, the guide answers as
    /// `BsdfSampled`.
    PathContinuation = 4,
}

/// Everything that shapes a guide. Fill it with `lodestar_guide_config_default`, then
/// change what you need. Enum fields are `uint32_t` holding one of the named enum's
/// values; anything else is `LODESTAR_STATUS_UNKNOWN_ENUM_VALUE`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarGuideConfig {
    /// `sizeof(LodestarGuideConfig)`: set by the default call; a mismatch means the
    /// header and library differ.
    pub struct_size: u32,
    /// One of `LodestarStructure`.
    pub structure: u32,
    /// Memory budget for all tables, bytes; sets the region count unless `region_count` does.
    pub budget_bytes: u64,
    /// An exact region (probe) count that must fit the budget; 0 fills the budget.
    pub region_count: u64,
    /// One of `LodestarMapping`.
    pub mapping: u32,
    /// Patches along the map's two axes; the product is the patch count (≤ 65536).
    pub resolution: [u32; 2],
    /// 1: place probes on both sides of every surface; 0: front side (the winding's normal).
    pub two_sided: u32,
    /// A hit uses the nearest probe whose normal is within this angle, degrees, (0, 180].
    pub max_normal_angle_deg: f32,
    /// Lookup shells searched around a hit, 1..=16 (each about one probe spacing).
    pub max_search_rings: u32,
    /// Q of every patch before learning, radiance, ≥ `q_floor`.
    pub initial_q: f32,
    /// Lower bound of every stored Q, radiance, > 0.
    pub q_floor: f32,
    /// Share of sampling probability spread uniformly over the patches, [0, 1].
    pub uniform_mix: f32,
    /// Exponent γ of the sampling weights Q^γ, (0, 1].
    pub sampling_exponent: f32,
    /// One of `LodestarLearningRate`.
    pub learning_rate: u32,
    /// α for `EXPONENTIAL`, the decay exponent for `GLOBAL`; ignored otherwise.
    pub learning_rate_parameter: f32,
    /// One of `LodestarIntegralEstimator`.
    pub integral_estimator: u32,
}

impl LodestarGuideConfig {
    /// The defaults of guiding-core's hemisphere grid.
    pub(crate) fn from_settings(s: &HemisphereGridSettings) -> Self {
        let (learning_rate, learning_rate_parameter, integral_estimator) = update_rule_to_c(&s.update_rule);
        Self {
            struct_size: size_of::<Self>() as u32,
            structure: LodestarStructure::HemisphereGrid as u32,
            budget_bytes: s.budget_bytes as u64,
            region_count: s.probe_count.unwrap_or(0) as u64,
            mapping: match s.layout.mapping {
                HemisphereMapping::Cylindrical => LodestarMapping::Cylindrical,
                HemisphereMapping::ConcentricSquare => LodestarMapping::ConcentricSquare,
                other => unreachable!("{other:?} has no C value yet: add it to LodestarMapping"),
            } as u32,
            resolution: s.layout.resolution,
            two_sided: s.two_sided as u32,
            max_normal_angle_deg: s.max_normal_angle_deg,
            max_search_rings: s.max_search_rings,
            initial_q: s.initial_q,
            q_floor: s.q_floor,
            uniform_mix: s.uniform_mix,
            sampling_exponent: s.sampling_exponent,
            learning_rate,
            learning_rate_parameter,
            integral_estimator,
        }
    }

    /// The hemisphere grid settings this config asks for: sizes, enums and numbers
    /// checked here, ranges by guiding-core.
    pub(crate) fn settings(&self) -> Result<HemisphereGridSettings, Failure> {
        check_struct_size(self.struct_size, size_of::<Self>(), "LodestarGuideConfig")?;
        if self.structure != LodestarStructure::HemisphereGrid as u32 {
            return Err(unknown(
                "structure",
                self.structure,
                "LodestarStructure (HEMISPHERE_GRID = 1; the others have their own create calls)",
            ));
        }
        let mapping = match self.mapping {
            0 => HemisphereMapping::Cylindrical,
            1 => HemisphereMapping::ConcentricSquare,
            other => return Err(unknown("mapping", other, "LodestarMapping (0, 1)")),
        };
        let update_rule =
            update_rule_from_c(self.learning_rate, self.learning_rate_parameter, self.integral_estimator)?;
        let two_sided = flag(self.two_sided, "two_sided")?;
        let budget_bytes = budget(self.budget_bytes)?;
        let probe_count = match self.region_count {
            0 => None,
            n => Some(usize::try_from(n).map_err(|_| {
                Failure::new(LodestarStatus::InvalidConfig, format!("`config->region_count` = {n} is too large"))
            })?),
        };
        let settings = HemisphereGridSettings {
            budget_bytes,
            probe_count,
            layout: PatchLayout { mapping, resolution: self.resolution },
            two_sided,
            max_normal_angle_deg: finite(self.max_normal_angle_deg, "config->max_normal_angle_deg")?,
            max_search_rings: self.max_search_rings,
            initial_q: finite(self.initial_q, "config->initial_q")?,
            q_floor: finite(self.q_floor, "config->q_floor")?,
            uniform_mix: finite(self.uniform_mix, "config->uniform_mix")?,
            sampling_exponent: finite(self.sampling_exponent, "config->sampling_exponent")?,
            // Not in the C struct (its layout is the ABI): C callers sample by Q alone.
            cosine_product: false,
            update_rule,
        };
        settings.validate().map_err(|e| Failure::from_core(&e, "config"))?;
        Ok(settings)
    }
}

/// `config->{field}` = `value` is not one of the `known` enum's values.
pub(crate) fn unknown(field: &str, value: u32, known: &str) -> Failure {
    Failure::new(LodestarStatus::UnknownEnumValue, format!("`config->{field}` = {value} is not one of {known}"))
}

/// A 0/1 config field.
pub(crate) fn flag(value: u32, field: &str) -> Result<bool, Failure> {
    match value {
        0 => Ok(false),
        1 => Ok(true),
        other => {
            Err(Failure::new(LodestarStatus::InvalidArgument, format!("`config->{field}` = {other} must be 0 or 1")))
        }
    }
}

/// A byte budget that fits this machine's `usize`.
pub(crate) fn budget(bytes: u64) -> Result<usize, Failure> {
    usize::try_from(bytes).map_err(|_| {
        Failure::new(LodestarStatus::InvalidConfig, format!("`config->budget_bytes` = {bytes} is too large"))
    })
}

/// A grid resolution of three cell counts; all zero asks the structure to size it.
pub(crate) fn resolution(cells: [u32; 3]) -> Option<[u32; 3]> {
    (cells != [0; 3]).then_some(cells)
}

/// The C fields (`learning_rate`, `learning_rate_parameter`, `integral_estimator`) of
/// an update rule.
pub(crate) fn update_rule_to_c(rule: &UpdateRule) -> (u32, f32, u32) {
    let (learning_rate, parameter) = match rule.learning_rate {
        LearningRate::SimpleAverage => (LodestarLearningRate::SimpleAverage, 0.0),
        LearningRate::RegionVisits => (LodestarLearningRate::RegionVisits, 0.0),
        LearningRate::Exponential { alpha } => (LodestarLearningRate::Exponential, alpha),
        LearningRate::Global { exponent } => (LodestarLearningRate::Global, exponent),
        other => unreachable!("{other:?} has no C value yet: add it to LodestarLearningRate"),
    };
    let integral = match rule.integral {
        IntegralEstimator::BsdfWeightedSum => LodestarIntegralEstimator::BsdfWeightedSum,
        IntegralEstimator::StratifiedPatches => LodestarIntegralEstimator::StratifiedPatches,
        IntegralEstimator::MaxEntry => LodestarIntegralEstimator::MaxEntry,
        IntegralEstimator::BsdfSampled => LodestarIntegralEstimator::BsdfSampled,
        IntegralEstimator::PathContinuation => LodestarIntegralEstimator::PathContinuation,
        other => unreachable!("{other:?} has no C value yet: add it to LodestarIntegralEstimator"),
    };
    (learning_rate as u32, parameter, integral as u32)
}

/// The update rule the C fields ask for (ranges are checked by guiding-core).
pub(crate) fn update_rule_from_c(learning_rate: u32, parameter: f32, integral: u32) -> Result<UpdateRule, Failure> {
    let parameter = finite(parameter, "config->learning_rate_parameter")?;
    let learning_rate = match learning_rate {
        0 => LearningRate::SimpleAverage,
        1 => LearningRate::RegionVisits,
        2 => LearningRate::Exponential { alpha: parameter },
        3 => LearningRate::Global { exponent: parameter },
        other => return Err(unknown("learning_rate", other, "LodestarLearningRate (0..=3)")),
    };
    let integral = match integral {
        0 => IntegralEstimator::BsdfWeightedSum,
        1 => IntegralEstimator::StratifiedPatches,
        2 => IntegralEstimator::MaxEntry,
        3 => IntegralEstimator::BsdfSampled,
        4 => IntegralEstimator::PathContinuation,
        other => return Err(unknown("integral_estimator", other, "LodestarIntegralEstimator (0..=4)")),
    };
    Ok(UpdateRule { learning_rate, integral })
}

/// Fills `out_config` with the defaults: a hemisphere grid of 8 × 16 cylindrical patches
/// in a 2 MiB budget, simple averaging (Eq. 2), the BSDF-weighted integral.
///
/// # Safety
/// `out_config` must be NULL or point to writable memory for a `LodestarGuideConfig`.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_config_default(out_config: *mut LodestarGuideConfig) -> LodestarStatus {
    guarded("lodestar_guide_config_default", || {
        // SAFETY: the caller's contract.
        let out = unsafe { Output::new(out_config, "out_config") }?;
        out.write(LodestarGuideConfig::from_settings(&HemisphereGridSettings::default()));
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_to_the_core_defaults() {
        let defaults = HemisphereGridSettings::default();
        let config = LodestarGuideConfig::from_settings(&defaults);
        assert_eq!(config.settings().unwrap(), defaults);
        assert_eq!(size_of::<LodestarGuideConfig>(), 80);
    }

    #[test]
    fn each_bad_field_names_itself() {
        let good = LodestarGuideConfig::from_settings(&HemisphereGridSettings::default());
        type Spoil = fn(&mut LodestarGuideConfig);
        let cases: [(Spoil, LodestarStatus, &str); 8] = [
            (|c| c.struct_size = 4, LodestarStatus::WrongStructSize, "struct_size"),
            (|c| c.structure = 7, LodestarStatus::UnknownEnumValue, "structure"),
            (|c| c.mapping = 2, LodestarStatus::UnknownEnumValue, "mapping"),
            (|c| c.learning_rate = 9, LodestarStatus::UnknownEnumValue, "learning_rate"),
            (|c| c.integral_estimator = 5, LodestarStatus::UnknownEnumValue, "integral_estimator"),
            (|c| c.initial_q = f32::NAN, LodestarStatus::NonFiniteArgument, "initial_q"),
            (|c| c.uniform_mix = 2.0, LodestarStatus::InvalidConfig, "uniform_mix"),
            (|c| c.two_sided = 2, LodestarStatus::InvalidArgument, "two_sided"),
        ];
        for (spoil, status, field) in cases {
            let mut config = good;
            spoil(&mut config);
            let failure = config.settings().unwrap_err();
            assert_eq!(failure.status, status, "{field}");
            assert!(failure.message.contains(field), "{}", failure.message);
        }
    }
}
