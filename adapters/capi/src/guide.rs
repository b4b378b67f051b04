//! The guide handle and the per-vertex calls: locate, sample, pdf, update, estimate.

use std::cell::Cell;
use std::ffi::c_void;

use glam::{Vec2, Vec3};
use guiding_core::{Guide, HemisphereGrid, Lambertian, ScatteringFunction, Triangle};

use crate::arguments::{borrow, direction, finite, merge_pair, point, slice, uniform, Output};
use crate::config::{LodestarGuideConfig, LodestarStructure};
use crate::status::{guarded, Failure, LodestarStatus};
use crate::structure::{with_structure, CRegions, GuideStructure};
use crate::types::{
    LodestarDirectionSample, LodestarGuideStats, LodestarRegion, LodestarUpdateOutcome, LodestarVec3,
    LODESTAR_NO_REGION,
};

/// An opaque guide of any structure: create with `lodestar_guide_create` (a hemisphere
/// grid over a mesh), `lodestar_guide_create_volume`, `_mixture` or `_tree` (over scene
/// bounds), or `lodestar_guide_load`; free with `lodestar_guide_release`.
pub struct LodestarGuide {
    pub(crate) structure: GuideStructure,
}

impl LodestarGuide {
    pub(crate) fn into_raw(self) -> *mut LodestarGuide {
        Box::into_raw(Box::new(self))
    }

    fn stats(&self) -> guiding_core::GuideStats {
        with_structure!(&self.structure, g => g.stats())
    }

    pub(crate) fn to_bytes(&self) -> Vec<u8> {
        with_structure!(&self.structure, g => g.to_bytes())
    }
}

/// Borrows a handle for a shared (thread-safe) call.
///
/// # Safety
/// A non-NULL `guide` must come from create/load and not yet be released.
unsafe fn shared<'a>(guide: *const LodestarGuide) -> Result<&'a LodestarGuide, Failure> {
    // SAFETY: the caller's contract.
    unsafe { borrow(guide, "guide") }
}

/// Creates a guide over a triangle mesh: `vertex_count` positions (3 floats each, scene
/// units) and `triangle_count` triangles (3 indices each, counter-clockwise seen from
/// the front, which is the side probes face unless `config->two_sided`). The guide keeps
/// no pointer to the arrays. On success `*out_guide` owns the new guide.
///
/// # Safety
/// Pointers must be NULL or valid: `config` for one config, `positions` for
/// `3·vertex_count` floats, `indices` for `3·triangle_count` indices, `out_guide` for
/// writing one pointer.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_create(
    config: *const LodestarGuideConfig,
    positions: *const f32,
    vertex_count: usize,
    indices: *const u32,
    triangle_count: usize,
    out_guide: *mut *mut LodestarGuide,
) -> LodestarStatus {
    guarded("lodestar_guide_create", || {
        // SAFETY (all four): the caller's contract.
        let config = unsafe { borrow(config, "config") }?;
        let coordinates = unsafe { slice(positions, vertex_count.saturating_mul(3), "positions") }?;
        let indices = unsafe { slice(indices, triangle_count.saturating_mul(3), "indices") }?;
        let out = unsafe { Output::new(out_guide, "out_guide") }?;
        let settings = config.settings()?;
        let vertex = |t: usize, corner: usize| -> Result<Vec3, Failure> {
            let v = indices[3 * t + corner] as usize;
            if v >= vertex_count {
                return Err(Failure::new(
                    LodestarStatus::InvalidArgument,
                    format!("`indices[{}]` = {v} (triangle {t}) is past vertex_count = {vertex_count}", 3 * t + corner),
                ));
            }
            let p = Vec3::from_slice(&coordinates[3 * v..3 * v + 3]);
            if !p.is_finite() {
                return Err(Failure::new(
                    LodestarStatus::NonFiniteArgument,
                    format!("`positions` of vertex {v} (triangle {t}) = ({}, {}, {}) is not finite", p.x, p.y, p.z),
                ));
            }
            Ok(p)
        };
        let triangles = (0..triangle_count)
            .map(|t| Ok(Triangle::new(vertex(t, 0)?, vertex(t, 1)?, vertex(t, 2)?)))
            .collect::<Result<Vec<_>, Failure>>()?;
        let grid = HemisphereGrid::build(&triangles, settings).map_err(|e| Failure::from_core(&e, "building"))?;
        out.write(LodestarGuide { structure: GuideStructure::Hemisphere(grid) }.into_raw());
        Ok(())
    })
}

/// Frees a guide. Needs the guide to itself: no other call on it may be in flight, and
/// the handle must not be used afterwards. NULL is `LODESTAR_STATUS_NULL_ARGUMENT`.
///
/// # Safety
/// `guide` must be NULL or a handle from create/load not yet released.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_release(guide: *mut LodestarGuide) -> LodestarStatus {
    guarded("lodestar_guide_release", || {
        // SAFETY: the caller's contract; checked non-NULL and aligned first.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        drop(unsafe { Box::from_raw(guide) });
        Ok(())
    })
}

/// Finds the region for a surface point `position` (scene units) whose unit `normal`
/// faces the side the path arrives from (normalised here; zero length is an error).
/// `out_region->index` is `LODESTAR_NO_REGION` where no region covers the point: the
/// caller samples its BSDF alone there. Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_region` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_locate(
    guide: *const LodestarGuide,
    position: LodestarVec3,
    normal: LodestarVec3,
    out_region: *mut LodestarRegion,
) -> LodestarStatus {
    guarded("lodestar_guide_locate", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_region, "out_region") }?;
        let position = point(position, "position")?;
        let normal = direction(normal, "normal")?;
        let none = LodestarRegion { index: LODESTAR_NO_REGION, flags: 0, normal: normal.into() };
        let region = with_structure!(&guide.structure, g => g.locate(position, normal).map_or(none, |r| g.to_c(r)));
        out.write(region);
        Ok(())
    })
}

/// Draws a direction ∝ Q in `region` from two uniform numbers in [0, 1]; the pdf is per
/// steradian and positive. Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_sample` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_sample(
    guide: *const LodestarGuide,
    region: LodestarRegion,
    u0: f32,
    u1: f32,
    out_sample: *mut LodestarDirectionSample,
) -> LodestarStatus {
    guarded("lodestar_guide_sample", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_sample, "out_sample") }?;
        let u = Vec2::new(uniform(u0, "u0")?, uniform(u1, "u1")?);
        let sample = with_structure!(&guide.structure, g => g.sample(g.region(region)?, u));
        out.write(LodestarDirectionSample { direction: sample.direction.into(), pdf: sample.pdf });
        Ok(())
    })
}

/// The density (per steradian) with which `region` samples `direction` (world space,
/// normalised here); 0 below the region's horizon. Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_pdf` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_pdf(
    guide: *const LodestarGuide,
    region: LodestarRegion,
    direction: LodestarVec3,
    out_pdf: *mut f32,
) -> LodestarStatus {
    guarded("lodestar_guide_pdf", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_pdf, "out_pdf") }?;
        let wi = self::direction(direction, "direction")?;
        let pdf = with_structure!(&guide.structure, g => g.pdf(g.region(region)?, wi));
        out.write(pdf);
        Ok(())
    })
}

/// Blends `target` (radiance arriving from `direction`: `Le + estimate_integral` at the
/// next vertex) into Q with the guide's update rule. A NaN or infinite target returns
/// `LODESTAR_STATUS_NON_FINITE_ARGUMENT`, a negative one
/// `LODESTAR_STATUS_INVALID_ARGUMENT`; neither is stored, both are counted in the stats.
/// Thread-safe (lock-free).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_outcome` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_update(
    guide: *const LodestarGuide,
    region: LodestarRegion,
    direction: LodestarVec3,
    target: f32,
    out_outcome: *mut LodestarUpdateOutcome,
) -> LodestarStatus {
    guarded("lodestar_guide_update", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_outcome, "out_outcome") }?;
        let wi = self::direction(direction, "direction")?;
        let outcome = with_structure!(&guide.structure, g => g.update(g.region(region)?, wi, target));
        out.write(LodestarUpdateOutcome::from_core(outcome, "target", target)?);
        Ok(())
    })
}

/// `lodestar_guide_update` for a direction the renderer drew with density `pdf` (per
/// steradian, > 0: the whole mixture's where guide and BSDF were mixed), so what is
/// learned does not depend on how directions were drawn. The tree learns only this way
/// (its plain update assumes a uniform density). Thread-safe (lock-free).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_outcome` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_update_sampled(
    guide: *const LodestarGuide,
    region: LodestarRegion,
    direction: LodestarVec3,
    target: f32,
    pdf: f32,
    out_outcome: *mut LodestarUpdateOutcome,
) -> LodestarStatus {
    guarded("lodestar_guide_update_sampled", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_outcome, "out_outcome") }?;
        let wi = self::direction(direction, "direction")?;
        if finite(pdf, "pdf")? <= 0.0 {
            return Err(Failure::new(LodestarStatus::InvalidArgument, format!("`pdf` = {pdf} is not positive")));
        }
        let outcome = with_structure!(&guide.structure, g => g.update_sampled(g.region(region)?, wi, target, pdf));
        out.write(LodestarUpdateOutcome::from_core(outcome, "target", target)?);
        Ok(())
    })
}

/// Which structure the guide is (one of `LodestarStructure`). Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_structure` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_structure(
    guide: *const LodestarGuide,
    out_structure: *mut u32,
) -> LodestarStatus {
    guarded("lodestar_guide_structure", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_structure, "out_structure") }?;
        out.write(match guide.structure {
            GuideStructure::Hemisphere(_) => LodestarStructure::HemisphereGrid,
            GuideStructure::Volume(_) => LodestarStructure::IrradianceVolume,
            GuideStructure::Mixture(_) => LodestarStructure::GaussianMixture,
            GuideStructure::Tree(_) => LodestarStructure::SpatialDirectionalTree,
        } as u32);
        Ok(())
    })
}

/// A renderer's cosine-weighted BSDF `fs(wi, wo)·|cos θi|` (per steradian, ≥ 0, finite)
/// for unit world directions `wi` (towards the light) and `wo` (towards the viewer).
/// Called synchronously on the calling thread; must not throw or unwind.
pub type LodestarEvalCos =
    Option<unsafe extern "C" fn(user_data: *mut c_void, wi: LodestarVec3, wo: LodestarVec3) -> f32>;

/// A C callback seen as a [`ScatteringFunction`]; remembers the first bad value it returned.
struct CallbackScattering {
    eval_cos: unsafe extern "C" fn(*mut c_void, LodestarVec3, LodestarVec3) -> f32,
    user_data: *mut c_void,
    first_bad_value: Cell<Option<f32>>,
}

impl ScatteringFunction for CallbackScattering {
    fn eval_cos(&self, wi: Vec3, wo: Vec3) -> f32 {
        // SAFETY: the caller of lodestar_guide_estimate_integral vouches for the callback.
        let value = unsafe { (self.eval_cos)(self.user_data, wi.into(), wo.into()) };
        if value.is_finite() && value >= 0.0 {
            value
        } else {
            if self.first_bad_value.get().is_none() {
                self.first_bad_value.set(Some(value));
            }
            0.0
        }
    }
}

fn estimate<S: ScatteringFunction>(
    guide: &LodestarGuide,
    region: LodestarRegion,
    wo: Vec3,
    bsdf: &S,
    u: Vec2,
) -> Result<f32, Failure> {
    with_structure!(&guide.structure, g => Ok(g.estimate_integral(g.region(region)?, wo, bsdf, u)))
}

/// Estimates Eq. (1)'s `∫ Q(region, ωi) fs(ωi, wo) cos θi dωi` (radiance) with the
/// guide's integral estimator, calling `eval_cos(user_data, wi, wo)` for the BSDF;
/// `u0`, `u1` in [0, 1] jitter the stratified estimator. `user_data` is passed through
/// untouched and may be NULL. A callback value that is NaN, infinite or negative fails
/// the call. Thread-safe when the callback is.
///
/// # Safety
/// `guide` must be NULL or a live handle; `eval_cos` NULL or a function safe to call
/// with `user_data`; `out_value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_estimate_integral(
    guide: *const LodestarGuide,
    region: LodestarRegion,
    wo: LodestarVec3,
    eval_cos: LodestarEvalCos,
    user_data: *mut c_void,
    u0: f32,
    u1: f32,
    out_value: *mut f32,
) -> LodestarStatus {
    guarded("lodestar_guide_estimate_integral", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_value, "out_value") }?;
        let eval_cos = eval_cos.ok_or_else(|| Failure::new(LodestarStatus::NullArgument, "`eval_cos` is NULL"))?;
        let wo = direction(wo, "wo")?;
        let u = Vec2::new(uniform(u0, "u0")?, uniform(u1, "u1")?);
        let bsdf = CallbackScattering { eval_cos, user_data, first_bad_value: Cell::new(None) };
        let value = estimate(guide, region, wo, &bsdf, u)?;
        if let Some(bad) = bsdf.first_bad_value.get() {
            let status =
                if bad.is_finite() { LodestarStatus::InvalidArgument } else { LodestarStatus::NonFiniteArgument };
            return Err(Failure::new(status, format!("`eval_cos` returned {bad}: it must be finite and ≥ 0")));
        }
        out.write(value);
        Ok(())
    })
}

/// `lodestar_guide_estimate_integral` for a Lambertian surface of `albedo` in [0, 1]
/// with unit shading `normal` (normalised here): the guide uses exact per-patch cosine
/// integrals, and with the default estimator the call costs one load. Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_estimate_integral_lambertian(
    guide: *const LodestarGuide,
    region: LodestarRegion,
    normal: LodestarVec3,
    albedo: f32,
    u0: f32,
    u1: f32,
    out_value: *mut f32,
) -> LodestarStatus {
    guarded("lodestar_guide_estimate_integral_lambertian", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_value, "out_value") }?;
        let normal = direction(normal, "normal")?;
        let albedo = finite(albedo, "albedo")?;
        if !(0.0..=1.0).contains(&albedo) {
            return Err(Failure::new(
                LodestarStatus::InvalidArgument,
                format!("`albedo` = {albedo} is outside [0, 1]"),
            ));
        }
        let u = Vec2::new(uniform(u0, "u0")?, uniform(u1, "u1")?);
        out.write(estimate(guide, region, normal, &Lambertian { normal, albedo }, u)?);
        Ok(())
    })
}

/// Rebuilds every region's sampling distribution from the learned Q and starts the next
/// learning epoch; call between passes. Needs the guide to itself: no other call on it
/// may be in flight.
///
/// # Safety
/// `guide` must be NULL or a live handle no other thread is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_rebuild(guide: *mut LodestarGuide) -> LodestarStatus {
    guarded("lodestar_guide_rebuild", || {
        // SAFETY: the caller's contract; checked non-NULL and aligned first.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        let guide = unsafe { &mut *guide };
        with_structure!(&mut guide.structure, g => g.rebuild_sampling());
        Ok(())
    })
}

/// Adds what `other` learned to `guide`, whose sampling reflects both afterwards. Both
/// must hold the same structure built over the same scene (mesh or bounds) with the same
/// config. Hemisphere grids merge exactly under simple averaging (a weighted mean
/// otherwise); irradiance volumes and trees merge into the union of their subdivisions,
/// each cell the mean of both weighted by their updates (exact where the two shapes
/// agree, an approximation where they differ; a tree's regions must be located again);
/// mixtures by pairing their lobes by direction and averaging their statistics (an
/// approximation). A tree or mixture must be rebuilt since its last updates. Any refusal
/// is `LODESTAR_STATUS_INVALID_ARGUMENT` naming why, and nothing changes.
/// Needs `guide` to itself; `other` is only read.
///
/// # Safety
/// `guide` must be NULL or a live handle no other call is using; `other` NULL or a live
/// handle.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_merge(
    guide: *mut LodestarGuide,
    other: *const LodestarGuide,
) -> LodestarStatus {
    guarded("lodestar_guide_merge", || {
        // SAFETY: the caller's contract.
        let (guide, other) = unsafe { merge_pair(guide, other) }?;
        match (&mut guide.structure, &other.structure) {
            (GuideStructure::Hemisphere(grid), GuideStructure::Hemisphere(theirs)) => merge(grid, theirs),
            (GuideStructure::Volume(volume), GuideStructure::Volume(theirs)) => merge(volume, theirs),
            (GuideStructure::Mixture(mixture), GuideStructure::Mixture(theirs)) => merge(mixture, theirs),
            (GuideStructure::Tree(tree), GuideStructure::Tree(theirs)) => merge(tree, theirs),
            _ => Err(Failure::new(
                LodestarStatus::InvalidArgument,
                "the two guides hold different structures (lodestar_guide_structure says which)".to_string(),
            )),
        }
    })
}

/// `guide.merge(other)` through guiding-core's `Guide::merge`, its refusal as a status.
fn merge<G: Guide>(guide: &mut G, other: &G) -> Result<(), Failure> {
    guide.merge(other).map_err(|e| Failure::from_core(&e, "merging"))
}

/// Forgets everything the guide learned: it samples and estimates as when it was
/// created (the same probes, or one region over the same bounds). Needs the guide to
/// itself. Regions located before are stale afterwards.
///
/// # Safety
/// `guide` must be NULL or a live handle no other thread is using.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_reset(guide: *mut LodestarGuide) -> LodestarStatus {
    guarded("lodestar_guide_reset", || {
        // SAFETY: the caller's contract; checked non-NULL and aligned first.
        unsafe { borrow(guide.cast_const(), "guide") }?;
        let guide = unsafe { &mut *guide };
        let fresh = |e: guiding_core::Error| Failure::from_core(&e, "resetting");
        match &mut guide.structure {
            GuideStructure::Hemisphere(grid) => grid.reset(),
            GuideStructure::Volume(volume) => {
                let (low, high) = volume.bounds();
                *volume = guiding_core::IrradianceVolume::new(low, high, *volume.settings()).map_err(fresh)?;
            }
            GuideStructure::Mixture(mixture) => {
                let (low, high) = mixture.bounds();
                *mixture = guiding_core::GaussianMixture::new(low, high, *mixture.settings()).map_err(fresh)?;
            }
            GuideStructure::Tree(tree) => tree.reset(),
        }
        Ok(())
    })
}

/// Sizes and counters. Thread-safe (a snapshot of counters others may be updating).
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_stats` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_stats(
    guide: *const LodestarGuide,
    out_stats: *mut LodestarGuideStats,
) -> LodestarStatus {
    guarded("lodestar_guide_stats", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let out = unsafe { Output::new(out_stats, "out_stats") }?;
        out.write(guide.stats().into());
        Ok(())
    })
}

/// Checks every stored value (finite, within range, consistent distributions);
/// `LODESTAR_STATUS_INVALID_STATE` names the first that is not. Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_validate(guide: *const LodestarGuide) -> LodestarStatus {
    guarded("lodestar_guide_validate", || {
        // SAFETY: the caller's contract.
        let guide = unsafe { shared(guide) }?;
        let result = with_structure!(&guide.structure, g => g.validate());
        result.map_err(|e| Failure::new(LodestarStatus::InvalidState, e.to_string()))
    })
}
