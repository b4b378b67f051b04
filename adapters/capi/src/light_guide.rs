//! The light guide handle: learned light selection for next-event estimation (the
//! seed's Eq. 3), per cell of a grid over the scene: pick a light for a shadow ray,
//! learn from what the ray brought, rebuild between passes, save and load.

use glam::Vec3;
use guiding_core::{LightCell, LightGuide, LightGuideSettings, LightUpdateRule};

use crate::arguments::{borrow, check_struct_size, finite, index_below, merge_pair, point, slice, uniform, Output};
use crate::serialize::write_bytes_or_size;
use crate::status::{guarded, Failure, LodestarStatus};
use crate::types::{LodestarUpdateOutcome, LodestarVec3};

/// How a light guide's V learns (`LodestarLightGuideConfig.rule`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarLightRule {
    /// Eq. (3): unoccluded shadow rays blend ‖C‖∞ into V, occluded ones leave it alone.
    UnoccludedAverage = 0,
    /// Eq. (3) with occluded rays blended in as zero: V is the mean contribution.
    MeanContribution = 1,
    /// V = (unoccluded rays + 1) / (rays + 2) times the light's power share.
    VisibilityRatio = 2,
}

/// Everything that shapes a light guide. Fill it with
/// `lodestar_light_guide_config_default`, then change what you need.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarLightGuideConfig {
    /// `sizeof(LodestarLightGuideConfig)`: set by the default call.
    pub struct_size: u32,
    /// One of `LodestarLightRule`.
    pub rule: u32,
    /// Memory budget for the per-cell tables, bytes; sets the grid unless `resolution` does.
    pub budget_bytes: u64,
    /// Cells along x, y and z; all three 0 fills the budget with near-cubic cells.
    pub resolution: [u32; 3],
    /// Share of each cell's selection probability in proportion to light power, [0, 1].
    pub power_mix: f32,
    /// Share spread uniformly over all lights, (0, 1]: keeps every light selectable.
    pub uniform_mix: f32,
}

impl LodestarLightGuideConfig {
    fn from_settings(s: &LightGuideSettings) -> Self {
        Self {
            struct_size: size_of::<Self>() as u32,
            rule: match s.rule {
                LightUpdateRule::UnoccludedAverage => LodestarLightRule::UnoccludedAverage,
                LightUpdateRule::MeanContribution => LodestarLightRule::MeanContribution,
                LightUpdateRule::VisibilityRatio => LodestarLightRule::VisibilityRatio,
                other => unreachable!("{other:?} has no C value yet: add it to LodestarLightRule"),
            } as u32,
            budget_bytes: s.budget_bytes as u64,
            resolution: s.resolution.unwrap_or([0; 3]),
            power_mix: s.power_mix,
            uniform_mix: s.uniform_mix,
        }
    }

    /// The settings this config asks for: size, enum and numbers checked here, ranges
    /// by guiding-core.
    fn settings(&self) -> Result<LightGuideSettings, Failure> {
        check_struct_size(self.struct_size, size_of::<Self>(), "LodestarLightGuideConfig")?;
        let rule = match self.rule {
            0 => LightUpdateRule::UnoccludedAverage,
            1 => LightUpdateRule::MeanContribution,
            2 => LightUpdateRule::VisibilityRatio,
            other => {
                return Err(Failure::new(
                    LodestarStatus::UnknownEnumValue,
                    format!("`config->rule` = {other} is not one of LodestarLightRule (0..=2)"),
                ))
            }
        };
        let budget_bytes = usize::try_from(self.budget_bytes).map_err(|_| {
            Failure::new(
                LodestarStatus::InvalidConfig,
                format!("`config->budget_bytes` = {} is too large", self.budget_bytes),
            )
        })?;
        let settings = LightGuideSettings {
            budget_bytes,
            resolution: (self.resolution != [0; 3]).then_some(self.resolution),
            power_mix: finite(self.power_mix, "config->power_mix")?,
            uniform_mix: finite(self.uniform_mix, "config->uniform_mix")?,
            rule,
        };
        settings.validate().map_err(|e| Failure::from_core(&e, "config"))?;
        Ok(settings)
    }
}

/// Fills `out_config` with guiding-core's light guide defaults (1 MiB, mean
/// contribution, power share 0.2, uniform share 0.01).
///
/// # Safety
/// `out_config` must be NULL or writable for a `LodestarLightGuideConfig`.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_config_default(
    out_config: *mut LodestarLightGuideConfig,
) -> LodestarStatus {
    guarded("lodestar_light_guide_config_default", || {
        // SAFETY: the caller's contract.
        let out = unsafe { Output::new(out_config, "out_config") }?;
        out.write(LodestarLightGuideConfig::from_settings(&LightGuideSettings::default()));
        Ok(())
    })
}

/// An opaque light guide. Create with `lodestar_light_guide_create` (or load), free with
/// `lodestar_light_guide_release`. `cell`, `select`, `probability`, `update`, `save` and
/// `serialized_size` are lock-free and may run from any number of threads at once;
/// `rebuild` and `release` need the guide to themselves.
pub struct LodestarLightGuide {
    guide: LightGuide,
}

/// Borrows a light guide for a call that reads it.
///
/// # Safety
/// A non-NULL `guide` must come from create or load and not yet be released.
unsafe fn shared<'a>(guide: *const LodestarLightGuide) -> Result<&'a LightGuide, Failure> {
    // SAFETY: the caller's contract.
    Ok(&unsafe { borrow(guide, "guide") }?.guide)
}

/// A cell index the guide has.
fn cell(guide: &LightGuide, cell: u32) -> Result<LightCell, Failure> {
    index_below(cell, guide.cell_count(), "cell", "cell").map(LightCell)
}

/// A light index the guide has.
fn light(guide: &LightGuide, light: u32) -> Result<u32, Failure> {
    index_below(light, guide.light_count(), "light", "light")
}

/// Creates a light guide over the box `low`..`high` (scene units) for `light_count`
/// lights of the given `powers` (any consistent unit, e.g. luminance × area; finite,
/// ≥ 0; all zero means equal); `*out_guide` owns it.
///
/// # Safety
/// `config` must be NULL or readable; `powers` NULL or readable for `light_count`
/// floats; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_create(
    config: *const LodestarLightGuideConfig,
    low: LodestarVec3,
    high: LodestarVec3,
    powers: *const f32,
    light_count: usize,
    out_guide: *mut *mut LodestarLightGuide,
) -> LodestarStatus {
    guarded("lodestar_light_guide_create", || {
        // SAFETY (all three): the caller's contract.
        let config = unsafe { borrow(config, "config") }?;
        let powers = unsafe { slice(powers, light_count, "powers") }?;
        let out = unsafe { Output::new(out_guide, "out_guide") }?;
        let settings = config.settings()?;
        let (low, high): (Vec3, Vec3) = (point(low, "low")?, point(high, "high")?);
        let guide = LightGuide::new(low, high, powers, settings).map_err(|e| Failure::from_core(&e, "creating"))?;
        out.write(Box::into_raw(Box::new(LodestarLightGuide { guide })));
        Ok(())
    })
}

/// Frees a light guide; the handle must not be used afterwards.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_release(guide: *mut LodestarLightGuide) -> LodestarStatus {
    guarded("lodestar_light_guide_release", || {
        // SAFETY: checked non-NULL and aligned; liveness and exclusivity are the caller's contract.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        drop(unsafe { Box::from_raw(guide) });
        Ok(())
    })
}

/// The cell holding `point` (points outside the bounds use the nearest cell).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_cell` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_cell(
    guide: *const LodestarLightGuide,
    position: LodestarVec3,
    out_cell: *mut u32,
) -> LodestarStatus {
    guarded("lodestar_light_guide_cell", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_cell, "out_cell") }?;
        let position = point(position, "position")?;
        let found = guide.locate(position).ok_or_else(|| {
            Failure::new(LodestarStatus::InvalidArgument, format!("`position` {position} has no cell"))
        })?;
        out.write(found.0);
        Ok(())
    })
}

/// Picks a light for a shadow ray from `cell` with the uniform number `u` in [0, 1]:
/// its index and the probability it had (exactly what `probability` reports).
///
/// # Safety
/// `guide` must be NULL or a live handle; the outputs NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_select(
    guide: *const LodestarLightGuide,
    cell: u32,
    u: f32,
    out_light: *mut u32,
    out_probability: *mut f32,
) -> LodestarStatus {
    guarded("lodestar_light_guide_select", || {
        // SAFETY (all three): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out_light = unsafe { Output::new(out_light, "out_light") }?;
        let out_probability = unsafe { Output::new(out_probability, "out_probability") }?;
        let choice = guide.select(self::cell(guide, cell)?, uniform(u, "u")?);
        out_light.write(choice.light);
        out_probability.write(choice.probability);
        Ok(())
    })
}

/// The probability with which `select` picks `light` from `cell` (what MIS needs for
/// emission found by scattering).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_probability` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_probability(
    guide: *const LodestarLightGuide,
    cell: u32,
    light: u32,
    out_probability: *mut f32,
) -> LodestarStatus {
    guarded("lodestar_light_guide_probability", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_probability, "out_probability") }?;
        out.write(guide.probability(self::cell(guide, cell)?, self::light(guide, light)?));
        Ok(())
    })
}

/// Learns from one shadow ray from `cell` to `light`: `unoccluded` (0 or 1) says whether
/// it arrived, `contribution` is ‖C‖∞ of its unshadowed contribution (radiance over the
/// light's whole area: divided by the pdf of the point chosen on it). A NaN or infinite
/// contribution returns `LODESTAR_STATUS_NON_FINITE_ARGUMENT`, a negative one
/// `LODESTAR_STATUS_INVALID_ARGUMENT`; neither is learned, both are counted.
/// Thread-safe (lock-free).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_outcome` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_update(
    guide: *const LodestarLightGuide,
    cell: u32,
    light: u32,
    contribution: f32,
    unoccluded: u32,
    out_outcome: *mut LodestarUpdateOutcome,
) -> LodestarStatus {
    guarded("lodestar_light_guide_update", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_outcome, "out_outcome") }?;
        let unoccluded = match unoccluded {
            0 => false,
            1 => true,
            other => {
                return Err(Failure::new(
                    LodestarStatus::InvalidArgument,
                    format!("`unoccluded` = {other} must be 0 or 1"),
                ))
            }
        };
        let (cell, light) = (self::cell(guide, cell)?, self::light(guide, light)?);
        out.write(LodestarUpdateOutcome::from_core(
            guide.update(cell, light, contribution, unoccluded),
            "contribution",
            contribution,
        )?);
        Ok(())
    })
}

/// Rebuilds every cell's selection from what it learned. Call between passes: no other
/// call on this guide may be in flight.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_rebuild(guide: *mut LodestarLightGuide) -> LodestarStatus {
    guarded("lodestar_light_guide_rebuild", || {
        // SAFETY: checked non-NULL and aligned; exclusivity is the caller's contract.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        unsafe { &mut *guide }.guide.rebuild_sampling();
        Ok(())
    })
}

/// Forgets everything the guide learned (selection by power and the uniform share, as
/// created). Needs the guide to itself.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_reset(guide: *mut LodestarLightGuide) -> LodestarStatus {
    guarded("lodestar_light_guide_reset", || {
        // SAFETY: checked non-NULL and aligned; exclusivity is the caller's contract.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        unsafe { &mut *guide }.guide.reset();
        Ok(())
    })
}

/// Adds what `other` learned (the same scene and settings, e.g. another node of a
/// render farm; loaded from its saved bytes) to `guide` and rebuilds it; exact, as
/// guiding-core's `LightGuide::merge` says. Guides of another scene or settings are
/// `LODESTAR_STATUS_INVALID_ARGUMENT` naming what differs, and nothing changes. Needs
/// `guide` to itself; `other` is only read.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using; `other` NULL or a live
/// handle.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_merge(
    guide: *mut LodestarLightGuide,
    other: *const LodestarLightGuide,
) -> LodestarStatus {
    guarded("lodestar_light_guide_merge", || {
        // SAFETY: the caller's contract.
        let (guide, other) = unsafe { merge_pair(guide, other) }?;
        guide.guide.merge(&other.guide).map_err(|e| Failure::from_core(&e, "merging"))
    })
}

/// Writes the guide (versioned, checksummed) to `buffer` and its length to
/// `*out_size`; with `buffer` NULL and `capacity` 0 only the size is written. When
/// `capacity` is too small nothing is written to `buffer`, `*out_size` receives the
/// size needed and the call returns `LODESTAR_STATUS_BUFFER_TOO_SMALL`.
///
/// # Safety
/// `guide` must be NULL or a live handle; `buffer` NULL or writable for `capacity`
/// bytes; `out_size` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_save(
    guide: *const LodestarLightGuide,
    buffer: *mut u8,
    capacity: usize,
    out_size: *mut usize,
) -> LodestarStatus {
    guarded("lodestar_light_guide_save", || {
        // SAFETY (all three): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_size, "out_size") }?;
        // SAFETY: `buffer` is NULL or writable for `capacity` bytes by the caller's contract.
        unsafe { write_bytes_or_size(&guide.to_bytes(), buffer, capacity, out) }
    })
}

/// Reads a light guide saved by `lodestar_light_guide_save` (the bytes are copied). A
/// damaged, truncated or foreign buffer returns `LODESTAR_STATUS_DECODE_FAILED` naming
/// what is wrong.
///
/// # Safety
/// `bytes` must be NULL or readable for `size` bytes; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_light_guide_load(
    bytes: *const u8,
    size: usize,
    out_guide: *mut *mut LodestarLightGuide,
) -> LodestarStatus {
    guarded("lodestar_light_guide_load", || {
        // SAFETY (both): the caller's contract.
        let bytes = unsafe { slice(bytes, size, "bytes") }?;
        let out = unsafe { Output::new(out_guide, "out_guide") }?;
        let guide = LightGuide::from_bytes(bytes).map_err(|e| Failure::from_core(&e, "loading"))?;
        out.write(Box::into_raw(Box::new(LodestarLightGuide { guide })));
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_to_the_core_defaults() {
        let defaults = LightGuideSettings::default();
        assert_eq!(LodestarLightGuideConfig::from_settings(&defaults).settings().unwrap(), defaults);
    }

    #[test]
    fn each_bad_field_names_itself() {
        let good = LodestarLightGuideConfig::from_settings(&LightGuideSettings::default());
        type Spoil = fn(&mut LodestarLightGuideConfig);
        let cases: [(Spoil, LodestarStatus, &str); 4] = [
            (|c| c.struct_size = 4, LodestarStatus::WrongStructSize, "struct_size"),
            (|c| c.rule = 3, LodestarStatus::UnknownEnumValue, "rule"),
            (|c| c.power_mix = f32::NAN, LodestarStatus::NonFiniteArgument, "power_mix"),
            (|c| c.uniform_mix = 0.0, LodestarStatus::InvalidConfig, "uniform_mix"),
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
