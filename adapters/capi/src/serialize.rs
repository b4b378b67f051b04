//! Saving a guide to a caller's byte buffer and loading it back.

use crate::arguments::{borrow, slice, Output};
use crate::guide::LodestarGuide;
use crate::status::{guarded, Failure, LodestarStatus};
use crate::structure::GuideStructure;

/// The bytes `lodestar_guide_save` writes for this guide now (it grows only if the
/// guide changes shape, which no call does). Thread-safe.
///
/// # Safety
/// `guide` must be NULL or a live handle; `out_size` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_serialized_size(
    guide: *const LodestarGuide,
    out_size: *mut usize,
) -> LodestarStatus {
    guarded("lodestar_guide_serialized_size", || {
        // SAFETY (both): the caller's contract.
        let guide = unsafe { borrow(guide, "guide") }?;
        let out = unsafe { Output::new(out_size, "out_size") }?;
        out.write(guide.to_bytes().len());
        Ok(())
    })
}

/// Writes the guide's learned state (versioned, checksummed) to `buffer`, and its length
/// to `*out_size`. When `capacity` is too small nothing is written to `buffer`,
/// `*out_size` receives the size needed and the call returns
/// `LODESTAR_STATUS_BUFFER_TOO_SMALL`. Thread-safe; concurrent updates may or may not be
/// included.
///
/// # Safety
/// `guide` must be NULL or a live handle; `buffer` NULL or writable for `capacity`
/// bytes; `out_size` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_save(
    guide: *const LodestarGuide,
    buffer: *mut u8,
    capacity: usize,
    out_size: *mut usize,
) -> LodestarStatus {
    guarded("lodestar_guide_save", || {
        // SAFETY (all three): the caller's contract.
        let guide = unsafe { borrow(guide, "guide") }?;
        unsafe { slice(buffer.cast_const(), capacity, "buffer") }?;
        let out = unsafe { Output::new(out_size, "out_size") }?;
        // SAFETY: `buffer` was checked, and is writable for `capacity` bytes by the caller's contract.
        unsafe { write_bytes(&guide.to_bytes(), buffer, capacity, out) }
    })
}

/// Copies `bytes` to the caller's `buffer` of `capacity` bytes and their length to `out`;
/// when they do not fit nothing is copied, `out` receives the length needed and the
/// call fails with `BUFFER_TOO_SMALL`.
///
/// # Safety
/// `buffer` must be writable for `capacity` bytes (checked non-NULL and aligned by the
/// caller's `slice`).
pub(crate) unsafe fn write_bytes(
    bytes: &[u8],
    buffer: *mut u8,
    capacity: usize,
    out: Output<usize>,
) -> Result<(), Failure> {
    if bytes.len() > capacity {
        out.write(bytes.len());
        return Err(Failure::new(
            LodestarStatus::BufferTooSmall,
            format!("`capacity` = {capacity} bytes, the guide needs {} (written to *out_size)", bytes.len()),
        ));
    }
    // SAFETY: `buffer` holds `capacity` ≥ `bytes.len()` writable bytes (the caller's
    // contract) and cannot overlap `bytes`, which the library allocated.
    unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), buffer, bytes.len()) };
    out.write(bytes.len());
    Ok(())
}

/// `write_bytes` for the save calls that also answer a size query: with `buffer` NULL
/// and `capacity` 0 only the length is written to `out`.
///
/// # Safety
/// `buffer` must be NULL or writable for `capacity` bytes.
pub(crate) unsafe fn write_bytes_or_size(
    bytes: &[u8],
    buffer: *mut u8,
    capacity: usize,
    out: Output<usize>,
) -> Result<(), Failure> {
    if buffer.is_null() && capacity == 0 {
        out.write(bytes.len());
        return Ok(());
    }
    // SAFETY (both): checked here, then writable for `capacity` bytes by the caller's contract.
    unsafe { slice(buffer.cast_const(), capacity, "buffer") }?;
    unsafe { write_bytes(bytes, buffer, capacity, out) }
}

/// Reads a guide of any structure saved by `lodestar_guide_save` (the bytes are copied; the buffer may
/// be freed afterwards). A damaged, truncated or foreign buffer returns
/// `LODESTAR_STATUS_DECODE_FAILED` naming the field and byte offset.
///
/// # Safety
/// `bytes` must be NULL or readable for `size` bytes; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_load(
    bytes: *const u8,
    size: usize,
    out_guide: *mut *mut LodestarGuide,
) -> LodestarStatus {
    guarded("lodestar_guide_load", || {
        // SAFETY (both): the caller's contract.
        let bytes = unsafe { slice(bytes, size, "bytes") }?;
        let out = unsafe { Output::new(out_guide, "out_guide") }?;
        let structure = GuideStructure::from_bytes(bytes).map_err(|e| Failure::from_core(&e, "loading"))?;
        out.write(LodestarGuide { structure }.into_raw());
        Ok(())
    })
}
