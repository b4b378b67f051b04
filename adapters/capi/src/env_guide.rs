//! The environment guide handle: learned environment sampling for next-event estimation,
//! per cell of a grid over the scene (the seed's Eq. 3 over tiles of the map, and the
//! sun as a lobe of its own): draw a direction towards the sky, learn from what arrived,
//! rebuild between passes, save and load.

use glam::{Vec2, Vec3};
use guiding_core::environment::{EnvCell, EnvLobe, EnvSample, EnvTileGuide, EnvironmentTiles, SunDisk};
use guiding_core::{DirectionalDistribution, EnvTileGuideSettings};

use crate::arguments::{
    borrow, check_struct_size, direction, finite, index_below, merge_pair, point, slice, uniform, Output,
};
use crate::config::{budget, resolution};
use crate::serialize::write_bytes_or_size;
use crate::status::{guarded, Failure, LodestarStatus};
use crate::types::{LodestarUpdateOutcome, LodestarVec3};

/// Everything that shapes an environment guide. Fill it with
/// `lodestar_env_guide_config_default`, then change what you need.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarEnvGuideConfig {
    /// `sizeof(LodestarEnvGuideConfig)`: set by the default call.
    pub struct_size: u32,
    /// Share of each cell's lobe probability in proportion to the lobes' power, [0, 1].
    pub power_mix: f32,
    /// Memory budget for the per-cell tables, bytes; sets the grid unless `resolution` does.
    pub budget_bytes: u64,
    /// Cells along x, y and z; all three 0 fills the budget with near-cubic cells.
    pub resolution: [u32; 3],
    /// Tiles across (azimuth) and down (elevation) the latitude-longitude map.
    pub tiles: [u32; 2],
    /// Share spread uniformly over the lobes with power, (0, 1].
    pub uniform_mix: f32,
}

impl LodestarEnvGuideConfig {
    fn from_settings(s: &EnvTileGuideSettings) -> Self {
        Self {
            struct_size: size_of::<Self>() as u32,
            power_mix: s.power_mix,
            budget_bytes: s.budget_bytes as u64,
            resolution: s.resolution.unwrap_or([0; 3]),
            tiles: s.tiles,
            uniform_mix: s.uniform_mix,
        }
    }

    fn settings(&self) -> Result<EnvTileGuideSettings, Failure> {
        check_struct_size(self.struct_size, size_of::<Self>(), "LodestarEnvGuideConfig")?;
        let settings = EnvTileGuideSettings {
            budget_bytes: budget(self.budget_bytes)?,
            resolution: resolution(self.resolution),
            tiles: self.tiles,
            power_mix: finite(self.power_mix, "config->power_mix")?,
            uniform_mix: finite(self.uniform_mix, "config->uniform_mix")?,
        };
        settings.validate().map_err(|e| Failure::from_core(&e, "config"))?;
        Ok(settings)
    }
}

/// A sun: a disk of uniform luminance seen from every point of the scene.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarSunDisk {
    /// Unit direction towards its centre, world space (normalised here).
    pub direction: LodestarVec3,
    /// Its angular radius, radians, in (0, π/2).
    pub angular_radius: f32,
    /// Its luminance (radiance), > 0.
    pub luminance: f32,
}

/// A direction towards the environment drawn by `lodestar_env_guide_sample`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LodestarEnvSample {
    /// Unit direction, world space.
    pub direction: LodestarVec3,
    /// Its density under the cell's whole distribution, per steradian (for MIS).
    pub pdf: f32,
    /// The lobe it came from (a tile, or the sun as the last lobe): pass the sample to
    /// `lodestar_env_guide_update` as it is.
    pub lobe: u32,
    /// Its density given that lobe, per steradian.
    pub lobe_pdf: f32,
}

impl From<EnvSample> for LodestarEnvSample {
    fn from(s: EnvSample) -> Self {
        Self { direction: s.direction.into(), pdf: s.pdf, lobe: s.lobe.0, lobe_pdf: s.lobe_pdf }
    }
}

/// An opaque environment guide. Create with `lodestar_env_guide_create` (or load), free
/// with `lodestar_env_guide_release`. `cell`, `sample`, `pdf`, `update`, `save` are
/// lock-free and may run from any number of threads at once; `rebuild` and `release`
/// need the guide to themselves.
pub struct LodestarEnvGuide {
    guide: EnvTileGuide,
}

/// The environment as the caller hands it: the map's luminance, its tiling and the sun.
///
/// # Safety
/// `luminance` must be NULL or readable for `width·height` floats; `sun` NULL or readable.
unsafe fn environment(
    luminance: *const f32,
    width: usize,
    height: usize,
    tiles: [u32; 2],
    sun: *const LodestarSunDisk,
) -> Result<(EnvironmentTiles, Option<SunDisk>), Failure> {
    let texels = width.checked_mul(height).ok_or_else(|| {
        Failure::new(LodestarStatus::InvalidArgument, format!("`width` × `height` = {width} × {height} is too large"))
    })?;
    // SAFETY (both): the caller's contract.
    let luminance = unsafe { slice(luminance, texels, "luminance") }?;
    if let Some(i) = luminance.iter().position(|l| !(l.is_finite() && *l >= 0.0)) {
        let status =
            if luminance[i].is_finite() { LodestarStatus::InvalidArgument } else { LodestarStatus::NonFiniteArgument };
        return Err(Failure::new(status, format!("`luminance[{i}]` = {} is not finite and ≥ 0", luminance[i])));
    }
    let tiles =
        EnvironmentTiles::new(width, height, luminance, tiles).map_err(|e| Failure::from_core(&e, "environment"))?;
    let sun = if sun.is_null() {
        None
    } else {
        let s = unsafe { borrow(sun, "sun") }?;
        let d = direction(s.direction, "sun->direction")?;
        let radius = finite(s.angular_radius, "sun->angular_radius")?;
        let luminance = finite(s.luminance, "sun->luminance")?;
        Some(SunDisk::new(d, radius, luminance).map_err(|e| Failure::from_core(&e, "sun"))?)
    };
    Ok((tiles, sun))
}

/// Borrows an environment guide for a call that reads it.
///
/// # Safety
/// A non-NULL `guide` must come from create or load and not yet be released.
unsafe fn shared<'a>(guide: *const LodestarEnvGuide) -> Result<&'a EnvTileGuide, Failure> {
    // SAFETY: the caller's contract.
    Ok(&unsafe { borrow(guide, "guide") }?.guide)
}

/// A cell index the guide has.
fn cell(guide: &EnvTileGuide, cell: u32) -> Result<EnvCell, Failure> {
    index_below(cell, guide.cell_count(), "cell", "cell").map(EnvCell)
}

/// Fills `out_config` with guiding-core's environment guide defaults (1 MiB, 32 × 16
/// tiles, power share 0.1, uniform share 0.01).
///
/// # Safety
/// `out_config` must be NULL or writable for a `LodestarEnvGuideConfig`.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_config_default(out_config: *mut LodestarEnvGuideConfig) -> LodestarStatus {
    guarded("lodestar_env_guide_config_default", || {
        // SAFETY: the caller's contract.
        unsafe { Output::new(out_config, "out_config") }?
            .write(LodestarEnvGuideConfig::from_settings(&EnvTileGuideSettings::default()));
        Ok(())
    })
}

/// Creates an environment guide over the box `low`..`high` (scene units) for a
/// latitude-longitude map of `width × height` texels whose `luminance` (row by row from
/// the top, +y up; finite, ≥ 0) it samples, and an optional `sun` (NULL: none).
/// `*out_guide` owns it; it keeps no pointer to the arrays.
///
/// # Safety
/// `config` NULL or readable; `luminance` NULL or readable for `width·height` floats;
/// `sun` NULL or readable; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_create(
    config: *const LodestarEnvGuideConfig,
    low: LodestarVec3,
    high: LodestarVec3,
    luminance: *const f32,
    width: usize,
    height: usize,
    sun: *const LodestarSunDisk,
    out_guide: *mut *mut LodestarEnvGuide,
) -> LodestarStatus {
    guarded("lodestar_env_guide_create", || {
        // SAFETY (all): the caller's contract.
        let settings = unsafe { borrow(config, "config") }?.settings()?;
        let out = unsafe { Output::new(out_guide, "out_guide") }?;
        let (tiles, sun) = unsafe { environment(luminance, width, height, settings.tiles, sun) }?;
        let (low, high): (Vec3, Vec3) = (point(low, "low")?, point(high, "high")?);
        let guide =
            EnvTileGuide::new(low, high, tiles, sun, settings).map_err(|e| Failure::from_core(&e, "creating"))?;
        out.write(Box::into_raw(Box::new(LodestarEnvGuide { guide })));
        Ok(())
    })
}

/// Frees an environment guide; the handle must not be used afterwards.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_release(guide: *mut LodestarEnvGuide) -> LodestarStatus {
    guarded("lodestar_env_guide_release", || {
        // SAFETY: checked non-NULL and aligned; liveness and exclusivity are the caller's contract.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        drop(unsafe { Box::from_raw(guide) });
        Ok(())
    })
}

/// The cell holding `position` (points outside the bounds use the nearest cell).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_cell` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_cell(
    guide: *const LodestarEnvGuide,
    position: LodestarVec3,
    out_cell: *mut u32,
) -> LodestarStatus {
    guarded("lodestar_env_guide_cell", || {
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

/// Draws a direction towards the environment from `cell` with three uniform numbers in
/// [0, 1]: `u_lobe` picks the tile (or the sun), `u0`, `u1` the direction in it.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_sample` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_sample(
    guide: *const LodestarEnvGuide,
    cell: u32,
    u_lobe: f32,
    u0: f32,
    u1: f32,
    out_sample: *mut LodestarEnvSample,
) -> LodestarStatus {
    guarded("lodestar_env_guide_sample", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_sample, "out_sample") }?;
        let u = Vec2::new(uniform(u0, "u0")?, uniform(u1, "u1")?);
        // The lobe draw needs [0, 1): 1 is the last lobe's edge.
        let u_lobe = uniform(u_lobe, "u_lobe")?.min(1.0 - f32::EPSILON / 2.0);
        out.write(guide.distribution(self::cell(guide, cell)?).sample_lobe(u_lobe, u).into());
        Ok(())
    })
}

/// The density (per steradian) with which `cell` draws `direction` (normalised here): what
/// MIS needs for environment light found by scattering.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_pdf` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_pdf(
    guide: *const LodestarEnvGuide,
    cell: u32,
    direction: LodestarVec3,
    out_pdf: *mut f32,
) -> LodestarStatus {
    guarded("lodestar_env_guide_pdf", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_pdf, "out_pdf") }?;
        let wi = self::direction(direction, "direction")?;
        out.write(guide.distribution(self::cell(guide, cell)?).pdf(wi));
        Ok(())
    })
}

/// Learns from a shadow ray drawn by `lodestar_env_guide_sample` from `cell`:
/// `integrand` is ‖f·L·cos θ‖∞ times its visibility (0 where it was occluded), with L
/// the radiance of the sample's lobe alone, not divided by any pdf. A NaN or infinite
/// integrand is `LODESTAR_STATUS_NON_FINITE_ARGUMENT`, a negative one
/// `LODESTAR_STATUS_INVALID_ARGUMENT`; neither is learned, both are counted.
/// Thread-safe (lock-free).
///
/// # Safety
/// `guide` must be NULL or a live handle; `sample` NULL or readable; `out_outcome` NULL
/// or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_update(
    guide: *const LodestarEnvGuide,
    cell: u32,
    sample: *const LodestarEnvSample,
    integrand: f32,
    out_outcome: *mut LodestarUpdateOutcome,
) -> LodestarStatus {
    guarded("lodestar_env_guide_update", || {
        // SAFETY (all three): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let sample = unsafe { borrow(sample, "sample") }?;
        let out = unsafe { Output::new(out_outcome, "out_outcome") }?;
        let cell = self::cell(guide, cell)?;
        let lobe = index_below(sample.lobe, guide.lobe_count(), "sample->lobe", "lobe")?;
        let core = EnvSample {
            direction: direction(sample.direction, "sample->direction")?,
            pdf: finite(sample.pdf, "sample->pdf")?,
            lobe: EnvLobe(lobe),
            lobe_pdf: finite(sample.lobe_pdf, "sample->lobe_pdf")?,
        };
        if core.lobe_pdf <= 0.0 {
            return Err(Failure::new(
                LodestarStatus::InvalidArgument,
                format!("`sample->lobe_pdf` = {} is not positive", core.lobe_pdf),
            ));
        }
        out.write(LodestarUpdateOutcome::from_core(guide.update(cell, &core, integrand), "integrand", integrand)?);
        Ok(())
    })
}

/// Rebuilds every cell's lobe probabilities from what it learned. Call between passes:
/// no other call on this guide may be in flight.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_rebuild(guide: *mut LodestarEnvGuide) -> LodestarStatus {
    guarded("lodestar_env_guide_rebuild", || {
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
pub unsafe extern "C" fn lodestar_env_guide_reset(guide: *mut LodestarEnvGuide) -> LodestarStatus {
    guarded("lodestar_env_guide_reset", || {
        // SAFETY: checked non-NULL and aligned; exclusivity is the caller's contract.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        unsafe { &mut *guide }.guide.reset();
        Ok(())
    })
}

/// Adds what `other` learned (the same scene and settings, e.g. another node of a
/// render farm; loaded from its saved bytes) to `guide` and rebuilds it; exact, as
/// guiding-core's `EnvTileGuide::merge` says. Guides of another scene or settings are
/// `LODESTAR_STATUS_INVALID_ARGUMENT` naming what differs, and nothing changes. Needs
/// `guide` to itself; `other` is only read.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using; `other` NULL or a live
/// handle.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_merge(
    guide: *mut LodestarEnvGuide,
    other: *const LodestarEnvGuide,
) -> LodestarStatus {
    guarded("lodestar_env_guide_merge", || {
        // SAFETY: the caller's contract.
        let (guide, other) = unsafe { merge_pair(guide, other) }?;
        guide.guide.merge(&other.guide).map_err(|e| Failure::from_core(&e, "merging"))
    })
}

/// Writes what the guide learned (versioned, checksummed, with a fingerprint of the
/// environment; the map itself is the caller's and is not stored) to `buffer` and its
/// length to `*out_size`; with `buffer` NULL and `capacity` 0 only the size is written.
/// When `capacity` is too small nothing is written to `buffer`, `*out_size` receives the
/// size needed and the call returns `LODESTAR_STATUS_BUFFER_TOO_SMALL`.
///
/// # Safety
/// `guide` must be NULL or a live handle; `buffer` NULL or writable for `capacity`
/// bytes; `out_size` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_save(
    guide: *const LodestarEnvGuide,
    buffer: *mut u8,
    capacity: usize,
    out_size: *mut usize,
) -> LodestarStatus {
    guarded("lodestar_env_guide_save", || {
        // SAFETY (all three): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_size, "out_size") }?;
        // SAFETY: `buffer` is NULL or writable for `capacity` bytes by the caller's contract.
        unsafe { write_bytes_or_size(&guide.to_bytes(), buffer, capacity, out) }
    })
}

/// Reads an environment guide saved by `lodestar_env_guide_save` for the same map and
/// sun it learned (`config->tiles` as it was created with): another environment is
/// `LODESTAR_STATUS_INVALID_ARGUMENT` naming it, a damaged buffer
/// `LODESTAR_STATUS_DECODE_FAILED`.
///
/// # Safety
/// As `lodestar_env_guide_create`, and `bytes` NULL or readable for `size` bytes.
#[no_mangle]
pub unsafe extern "C" fn lodestar_env_guide_load(
    config: *const LodestarEnvGuideConfig,
    bytes: *const u8,
    size: usize,
    luminance: *const f32,
    width: usize,
    height: usize,
    sun: *const LodestarSunDisk,
    out_guide: *mut *mut LodestarEnvGuide,
) -> LodestarStatus {
    guarded("lodestar_env_guide_load", || {
        // SAFETY (all): the caller's contract.
        let settings = unsafe { borrow(config, "config") }?.settings()?;
        let bytes = unsafe { slice(bytes, size, "bytes") }?;
        let out = unsafe { Output::new(out_guide, "out_guide") }?;
        let (tiles, sun) = unsafe { environment(luminance, width, height, settings.tiles, sun) }?;
        let guide = EnvTileGuide::from_bytes(bytes, tiles, sun).map_err(|e| Failure::from_core(&e, "loading"))?;
        out.write(Box::into_raw(Box::new(LodestarEnvGuide { guide })));
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_to_the_core_defaults() {
        let defaults = EnvTileGuideSettings::default();
        assert_eq!(LodestarEnvGuideConfig::from_settings(&defaults).settings().unwrap(), defaults);
    }

    #[test]
    fn each_bad_field_names_itself() {
        let good = LodestarEnvGuideConfig::from_settings(&EnvTileGuideSettings::default());
        type Spoil = fn(&mut LodestarEnvGuideConfig);
        let cases: [(Spoil, LodestarStatus, &str); 4] = [
            (|c| c.struct_size = 4, LodestarStatus::WrongStructSize, "struct_size"),
            (|c| c.power_mix = f32::INFINITY, LodestarStatus::NonFiniteArgument, "power_mix"),
            (|c| c.uniform_mix = 0.0, LodestarStatus::InvalidConfig, "uniform_mix"),
            (|c| c.tiles = [0, 8], LodestarStatus::InvalidConfig, "tiles"),
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
