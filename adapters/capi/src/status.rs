//! Status codes, the per-thread error message, and the guard every entry point runs in.

use std::cell::RefCell;
use std::ffi::{c_char, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use guiding_core::Error;

/// What a call did. Every function but `lodestar_version`,
/// `lodestar_last_error` and `lodestar_status_name` returns one; on anything but
/// `LODESTAR_STATUS_OK` nothing was written to the outputs and
/// `lodestar_last_error` has the details.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarStatus {
    /// Success.
    Ok = 0,
    /// A required pointer was NULL (or misaligned for its type).
    NullArgument = 1,
    /// A number was NaN or infinite.
    NonFiniteArgument = 2,
    /// An argument is out of its range (a zero-length vector, an index past the end,
    /// a uniform number outside [0, 1], a negative target, a callback's bad value).
    InvalidArgument = 3,
    /// An enum field holds a value this version does not know.
    UnknownEnumValue = 4,
    /// `struct_size` does not match the struct this library was built with.
    WrongStructSize = 5,
    /// The output buffer is too small; the size needed was written.
    BufferTooSmall = 6,
    /// The region is not one of this guide's (stale, or `LODESTAR_NO_REGION`).
    InvalidRegion = 7,
    /// A configuration value is out of range, or the budget cannot hold the guide.
    InvalidConfig = 8,
    /// The triangles give no usable surface (no area, or a bad triangle).
    InvalidGeometry = 9,
    /// A serialized guide is damaged, truncated, foreign or from another version.
    DecodeFailed = 10,
    /// The guide's stored state failed validation.
    InvalidState = 11,
    /// An internal error (a caught panic): please report it with the message.
    InternalError = 12,
}

/// Why a call failed: a status and a message naming the argument or field.
#[derive(Debug)]
pub(crate) struct Failure {
    pub(crate) status: LodestarStatus,
    pub(crate) message: String,
}

impl Failure {
    pub(crate) fn new(status: LodestarStatus, message: impl Into<String>) -> Self {
        Self { status, message: message.into() }
    }

    /// A core error, classified by what went wrong.
    pub(crate) fn from_core(error: &Error, during: &str) -> Self {
        let status = match error {
            Error::InvalidSetting { .. }
            | Error::BudgetTooSmall { .. }
            | Error::OverBudget { .. }
            | Error::ResolutionTooLarge { .. } => LodestarStatus::InvalidConfig,
            Error::NoSurface | Error::NonFiniteTriangle { .. } | Error::InvalidProbe { .. } => {
                LodestarStatus::InvalidGeometry
            }
            Error::Decode(_) => LodestarStatus::DecodeFailed,
            Error::Incompatible { .. } => LodestarStatus::InvalidArgument,
            // An error this C layer does not classify yet: its message still says what.
            _ => LodestarStatus::InternalError,
        };
        Self::new(status, format!("{during}: {error}"))
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    // Interior NULs cannot occur in our messages, but a caller's data could carry one.
    let text = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    LAST_ERROR.with(|slot| *slot.borrow_mut() = text);
}

/// Runs an entry point's body: catches any panic, records the outcome as this thread's
/// last error (empty on success) and returns the status.
pub(crate) fn guarded(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> LodestarStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            set_last_error("");
            LodestarStatus::Ok
        }
        Ok(Err(failure)) => {
            set_last_error(&format!("{function}: {}", failure.message));
            failure.status
        }
        Err(payload) => {
            let detail = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            set_last_error(&format!("{function}: internal error: {detail}"));
            LodestarStatus::InternalError
        }
    }
}

/// The message of this thread's last call: what was wrong and where, or an empty string
/// after a call that succeeded. The pointer stays valid until this thread's next call
/// into the library; never NULL.
#[no_mangle]
pub extern "C" fn lodestar_last_error() -> *const c_char {
    catch_unwind(|| LAST_ERROR.with(|slot| slot.borrow().as_ptr())).unwrap_or(c"internal error".as_ptr())
}

/// The constant name of a status, e.g. `"LODESTAR_STATUS_NULL_ARGUMENT"`; unknown values
/// give `"LODESTAR_STATUS_UNKNOWN"`. Static storage; never NULL.
#[no_mangle]
pub extern "C" fn lodestar_status_name(status: i32) -> *const c_char {
    let name = match status {
        0 => c"LODESTAR_STATUS_OK",
        1 => c"LODESTAR_STATUS_NULL_ARGUMENT",
        2 => c"LODESTAR_STATUS_NON_FINITE_ARGUMENT",
        3 => c"LODESTAR_STATUS_INVALID_ARGUMENT",
        4 => c"LODESTAR_STATUS_UNKNOWN_ENUM_VALUE",
        5 => c"LODESTAR_STATUS_WRONG_STRUCT_SIZE",
        6 => c"LODESTAR_STATUS_BUFFER_TOO_SMALL",
        7 => c"LODESTAR_STATUS_INVALID_REGION",
        8 => c"LODESTAR_STATUS_INVALID_CONFIG",
        9 => c"LODESTAR_STATUS_INVALID_GEOMETRY",
        10 => c"LODESTAR_STATUS_DECODE_FAILED",
        11 => c"LODESTAR_STATUS_INVALID_STATE",
        12 => c"LODESTAR_STATUS_INTERNAL_ERROR",
        _ => c"LODESTAR_STATUS_UNKNOWN",
    };
    name.as_ptr()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    fn last_error() -> String {
        unsafe { CStr::from_ptr(lodestar_last_error()) }.to_string_lossy().into_owned()
    }

    #[test]
    fn a_panic_becomes_an_internal_error_with_its_message() {
        let status = guarded("lodestar_test", || panic!("boom"));
        assert_eq!(status, LodestarStatus::InternalError);
        assert_eq!(last_error(), "lodestar_test: internal error: boom");
        assert_eq!(guarded("lodestar_test", || Ok(())), LodestarStatus::Ok);
        assert_eq!(last_error(), "");
    }

    #[test]
    fn every_status_has_its_name() {
        for (code, status) in [
            (0, LodestarStatus::Ok),
            (1, LodestarStatus::NullArgument),
            (6, LodestarStatus::BufferTooSmall),
            (12, LodestarStatus::InternalError),
        ] {
            assert_eq!(status as i32, code);
        }
        let name = |code| unsafe { CStr::from_ptr(lodestar_status_name(code)) }.to_str().unwrap().to_string();
        assert_eq!(name(LodestarStatus::DecodeFailed as i32), "LODESTAR_STATUS_DECODE_FAILED");
        assert_eq!(name(99), "LODESTAR_STATUS_UNKNOWN");
        assert_eq!(name(-1), "LODESTAR_STATUS_UNKNOWN");
    }
}
