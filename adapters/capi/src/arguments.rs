//! Checks on what a C caller hands in: pointers, numbers, vectors, array sizes.

use glam::Vec3;

use crate::status::{Failure, LodestarStatus};
use crate::types::LodestarVec3;

fn null(name: &str) -> Failure {
    Failure::new(LodestarStatus::NullArgument, format!("`{name}` is NULL"))
}

fn check_pointer<T>(pointer: *const T, name: &str) -> Result<(), Failure> {
    if pointer.is_null() {
        return Err(null(name));
    }
    if !pointer.is_aligned() {
        return Err(Failure::new(
            LodestarStatus::NullArgument,
            format!("`{name}` is misaligned for its type (needs {} bytes)", std::mem::align_of::<T>()),
        ));
    }
    Ok(())
}

/// Borrows what `pointer` points to, after checking it is non-NULL and aligned.
///
/// # Safety
/// A non-NULL `pointer` must point to a valid `T` that outlives `'a`.
pub(crate) unsafe fn borrow<'a, T>(pointer: *const T, name: &str) -> Result<&'a T, Failure> {
    check_pointer(pointer, name)?;
    // SAFETY: non-NULL and aligned; validity is the caller's contract.
    Ok(unsafe { &*pointer })
}

/// Borrows `guide` to change and `other` to read, for a merge: both checked non-NULL
/// and aligned, and two different handles.
///
/// # Safety
/// Non-NULL pointers must point to live values; no other call may use `guide`.
pub(crate) unsafe fn merge_pair<'a, T>(guide: *mut T, other: *const T) -> Result<(&'a mut T, &'a T), Failure> {
    check_pointer(guide.cast_const(), "guide")?;
    check_pointer(other, "other")?;
    if std::ptr::eq(guide.cast_const(), other) {
        return Err(Failure::new(LodestarStatus::InvalidArgument, "`other` is `guide` itself".to_string()));
    }
    // SAFETY: checked above; validity and exclusivity are the caller's contract, and the
    // two do not alias.
    Ok(unsafe { (&mut *guide, &*other) })
}

/// An output location, checked up front so a call fails before doing any work.
pub(crate) struct Output<T>(*mut T);

impl<T> Output<T> {
    /// # Safety
    /// A non-NULL `pointer` must be valid for writing a `T` when `write` runs.
    pub(crate) unsafe fn new(pointer: *mut T, name: &str) -> Result<Self, Failure> {
        check_pointer(pointer.cast_const(), name)?;
        Ok(Self(pointer))
    }

    pub(crate) fn write(self, value: T) {
        // SAFETY: checked non-NULL and aligned in `new`, whose contract covers validity.
        unsafe { self.0.write(value) }
    }
}

/// A slice of `len` elements at `pointer`, with `len · size_of::<T>()` checked to fit.
///
/// # Safety
/// A non-NULL `pointer` must point to `len` valid elements that outlive `'a`.
pub(crate) unsafe fn slice<'a, T>(pointer: *const T, len: usize, name: &str) -> Result<&'a [T], Failure> {
    check_pointer(pointer, name)?;
    if len.checked_mul(std::mem::size_of::<T>()).is_none_or(|bytes| bytes > isize::MAX as usize) {
        return Err(Failure::new(LodestarStatus::InvalidArgument, format!("`{name}` length {len} is too large")));
    }
    // SAFETY: non-NULL, aligned, size fits isize; validity is the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(pointer, len) })
}

/// A finite number.
pub(crate) fn finite(value: f32, name: &str) -> Result<f32, Failure> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Failure::new(LodestarStatus::NonFiniteArgument, format!("`{name}` is {value}")))
    }
}

/// A point with finite coordinates.
pub(crate) fn point(value: LodestarVec3, name: &str) -> Result<Vec3, Failure> {
    let v = Vec3::from(value);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Failure::new(
            LodestarStatus::NonFiniteArgument,
            format!("`{name}` = ({}, {}, {}) is not finite", v.x, v.y, v.z),
        ))
    }
}

/// `v` scaled to unit length, or `None` for zero length. Scaled by its largest component
/// first: a tiny vector's squared length is denormal (or 0), and normalising it directly
/// gives a vector that is not of unit length.
pub(crate) fn unit(v: Vec3) -> Option<Vec3> {
    let largest = v.abs().max_element();
    (largest > 0.0 && largest.is_finite()).then(|| (v / largest).normalize())
}

/// A direction: finite and of non-zero length, returned normalised.
pub(crate) fn direction(value: LodestarVec3, name: &str) -> Result<Vec3, Failure> {
    let v = point(value, name)?;
    unit(v).ok_or_else(|| {
        Failure::new(
            LodestarStatus::InvalidArgument,
            format!("`{name}` = ({}, {}, {}) has no direction (zero length)", v.x, v.y, v.z),
        )
    })
}

/// An index a caller passed, checked below `count`: `name` is the argument, `what` what
/// it counts ("cell", "light"). Anything else is `INVALID_ARGUMENT` naming both.
pub(crate) fn index_below(value: u32, count: usize, name: &str, what: &str) -> Result<u32, Failure> {
    if (value as usize) < count {
        Ok(value)
    } else {
        Err(Failure::new(
            LodestarStatus::InvalidArgument,
            format!("`{name}` = {value} is not a {what} of this guide (it has {count})"),
        ))
    }
}

/// A uniform random number in [0, 1].
pub(crate) fn uniform(value: f32, name: &str) -> Result<f32, Failure> {
    finite(value, name)?;
    if (0.0..=1.0).contains(&value) {
        Ok(value)
    } else {
        Err(Failure::new(LodestarStatus::InvalidArgument, format!("`{name}` = {value} is outside [0, 1]")))
    }
}

/// Checks a config's `struct_size` against the library's `expected` size of `type_name`.
pub(crate) fn check_struct_size(found: u32, expected: usize, type_name: &str) -> Result<(), Failure> {
    if found as usize == expected {
        return Ok(());
    }
    Err(Failure::new(
        LodestarStatus::WrongStructSize,
        format!(
            "`config->struct_size` is {found} but this library's {type_name} has {expected} bytes \
             (header and library versions differ, or the config was not initialised)"
        ),
    ))
}
