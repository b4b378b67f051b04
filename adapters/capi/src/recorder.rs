//! The path recorder handle: a renderer records each vertex of a path as it traces,
//! says what arrived along the last direction, and at path end teaches a guide every
//! target of Eq. (1) (guiding-core's `PathRecorder`), so the target logic — carried
//! through delta vertices with 1/survival, split between next-event estimation and
//! scattering — is not re-derived in C.

use guiding_core::{PathRecorder, UpdateOutcome};

use crate::arguments::{borrow, direction, finite, point, Output};
use crate::guide::LodestarGuide;
use crate::status::{guarded, Failure, LodestarStatus};
use crate::structure::{with_structure, CRegions};
use crate::types::{LodestarRegion, LodestarVec3, LODESTAR_NO_REGION};

/// An opaque path recorder: one per thread (its calls are not thread-safe; each thread
/// records its own path). Create with `lodestar_path_recorder_create`, free with
/// `lodestar_path_recorder_release`.
pub struct LodestarPathRecorder {
    /// Regions as the caller handed them; checked against the guide at learn.
    path: PathRecorder<LodestarRegion>,
}

/// Borrows a recorder for a call that changes it.
///
/// # Safety
/// A non-NULL `recorder` must come from create and not yet be released, and no other
/// call on it may be in flight.
unsafe fn exclusive<'a>(recorder: *mut LodestarPathRecorder) -> Result<&'a mut LodestarPathRecorder, Failure> {
    // SAFETY: checked non-NULL and aligned; validity and exclusivity are the caller's contract.
    unsafe { borrow(recorder.cast_const(), "recorder") }?;
    Ok(unsafe { &mut *recorder })
}

/// A non-negative finite number.
fn non_negative(value: f32, name: &str) -> Result<f32, Failure> {
    finite(value, name)?;
    if value >= 0.0 {
        Ok(value)
    } else {
        Err(Failure::new(LodestarStatus::InvalidArgument, format!("`{name}` = {value} is negative")))
    }
}

/// Creates an empty recorder; `*out_recorder` owns it.
///
/// # Safety
/// `out_recorder` must be NULL or valid for writing one pointer.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_create(out_recorder: *mut *mut LodestarPathRecorder) -> LodestarStatus {
    guarded("lodestar_path_recorder_create", || {
        // SAFETY: the caller's contract.
        let out = unsafe { Output::new(out_recorder, "out_recorder") }?;
        out.write(Box::into_raw(Box::new(LodestarPathRecorder { path: PathRecorder::new() })));
        Ok(())
    })
}

/// Frees a recorder; the handle must not be used afterwards.
///
/// # Safety
/// `recorder` must be NULL or a handle from create not yet released.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_release(recorder: *mut LodestarPathRecorder) -> LodestarStatus {
    guarded("lodestar_path_recorder_release", || {
        // SAFETY: the caller's contract; checked non-NULL and aligned first.
        unsafe { exclusive(recorder) }?;
        drop(unsafe { Box::from_raw(recorder) });
        Ok(())
    })
}

/// Forgets the recorded path (keeping its memory): call before each path.
///
/// # Safety
/// `recorder` must be NULL or a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_clear(recorder: *mut LodestarPathRecorder) -> LodestarStatus {
    guarded("lodestar_path_recorder_clear", || {
        // SAFETY: the caller's contract.
        unsafe { exclusive(recorder) }?.path.clear();
        Ok(())
    })
}

/// Records a vertex at `origin` (scene units) that scattered along `direction`
/// (normalised here), drawn with density `pdf` (per steradian, > 0; the whole mixture's
/// where the guide and the BSDF were mixed). `region` is what `lodestar_guide_locate`
/// gave here, or `LODESTAR_NO_REGION` (the vertex then learns nothing and a predecessor
/// that carries gets its target). `throughput` is the path's (luminance, ≥ 0) for what
/// arrives along `direction`.
///
/// # Safety
/// `recorder` must be NULL or a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_scattered(
    recorder: *mut LodestarPathRecorder,
    region: LodestarRegion,
    origin: LodestarVec3,
    direction: LodestarVec3,
    pdf: f32,
    throughput: f32,
) -> LodestarStatus {
    guarded("lodestar_path_recorder_scattered", || {
        // SAFETY: the caller's contract.
        let recorder = unsafe { exclusive(recorder) }?;
        let origin = point(origin, "origin")?;
        let wi = self::direction(direction, "direction")?;
        if finite(pdf, "pdf")? <= 0.0 {
            return Err(Failure::new(LodestarStatus::InvalidArgument, format!("`pdf` = {pdf} is not positive")));
        }
        let throughput = non_negative(throughput, "throughput")?;
        let region = (region.index != LODESTAR_NO_REGION).then_some(region);
        recorder.path.scattered(region, origin, wi, pdf, throughput, ());
        Ok(())
    })
}

/// The last recorded direction reached a surface `distance` away (scene units, ≥ 0).
///
/// # Safety
/// `recorder` must be NULL or a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_reached(
    recorder: *mut LodestarPathRecorder,
    distance: f32,
) -> LodestarStatus {
    guarded("lodestar_path_recorder_reached", || {
        // SAFETY: the caller's contract.
        let recorder = unsafe { exclusive(recorder) }?;
        recorder.path.reached(non_negative(distance, "distance")?);
        Ok(())
    })
}

/// Radiance (luminance, ≥ 0) arrived along the last recorded direction: the emission
/// seen there times its MIS weight against next-event estimation, or the light that the
/// vertex there reflected back from its own light sample. Calls add up.
///
/// # Safety
/// `recorder` must be NULL or a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_arrive(
    recorder: *mut LodestarPathRecorder,
    radiance: f32,
) -> LodestarStatus {
    guarded("lodestar_path_recorder_arrive", || {
        // SAFETY: the caller's contract.
        let recorder = unsafe { exclusive(recorder) }?;
        recorder.path.arrive(non_negative(radiance, "radiance")?);
        Ok(())
    })
}

/// The vertex the last recorded direction reached estimates Eq. (1)'s integral there
/// (≥ 0; `lodestar_guide_estimate_integral` gives one).
///
/// # Safety
/// `recorder` must be NULL or a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_estimate(
    recorder: *mut LodestarPathRecorder,
    integral: f32,
) -> LodestarStatus {
    guarded("lodestar_path_recorder_estimate", || {
        // SAFETY: the caller's contract.
        let recorder = unsafe { exclusive(recorder) }?;
        recorder.path.estimate(non_negative(integral, "integral")?);
        Ok(())
    })
}

/// The vertex the last recorded direction reached has no estimate of its own (a delta
/// surface, no region, or a renderer that learns from the path's continuation): it
/// passes its own target back times `factor` (≥ 0: its fs·cos/pdf and, where Russian
/// roulette ran there, 1/survival, as the throughput has it).
///
/// # Safety
/// `recorder` must be NULL or a live handle used by this thread alone.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_carry(
    recorder: *mut LodestarPathRecorder,
    factor: f32,
) -> LodestarStatus {
    guarded("lodestar_path_recorder_carry", || {
        // SAFETY: the caller's contract.
        let recorder = unsafe { exclusive(recorder) }?;
        recorder.path.carry(non_negative(factor, "factor")?);
        Ok(())
    })
}

/// Teaches `guide` the recorded path: every vertex with a region learns its target of
/// Eq. (1), weighed by the density its direction was drawn with. Every region is checked
/// first: a stale one fails the call with `LODESTAR_STATUS_INVALID_REGION` and the guide
/// learns nothing from the path. `*out_accepted` gets how many updates the guide stored.
/// Thread-safe on the guide (lock-free), as `lodestar_guide_update`.
///
/// # Safety
/// `recorder` must be NULL or a live handle not being changed by another thread; `guide`
/// NULL or a live handle; `out_accepted` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_path_recorder_learn(
    recorder: *const LodestarPathRecorder,
    guide: *const LodestarGuide,
    out_accepted: *mut usize,
) -> LodestarStatus {
    guarded("lodestar_path_recorder_learn", || {
        // SAFETY (all three): the caller's contract.
        let recorder = unsafe { borrow(recorder, "recorder") }?;
        let guide = unsafe { borrow(guide, "guide") }?;
        let out = unsafe { Output::new(out_accepted, "out_accepted") }?;
        let accepted = with_structure!(&guide.structure, g => learn(&recorder.path, g)?);
        out.write(accepted);
        Ok(())
    })
}

/// Checks every recorded region against `guide`, then teaches it each target weighed by
/// its direction's density; how many updates it stored.
fn learn<G: CRegions>(path: &PathRecorder<LodestarRegion>, guide: &G) -> Result<usize, Failure> {
    for (i, vertex) in path.vertices().iter().enumerate() {
        if let Some(region) = vertex.region {
            guide.region(region).map_err(|f| Failure::new(f.status, format!("vertex {i}: {}", f.message)))?;
        }
    }
    let mut accepted = 0;
    for (vertex, target) in path.targets() {
        let Some(region) = vertex.region.map(|r| guide.region(r)).transpose()? else { continue };
        accepted +=
            (guide.update_sampled(region, vertex.direction, target, vertex.pdf) == UpdateOutcome::Accepted) as usize;
    }
    Ok(accepted)
}
