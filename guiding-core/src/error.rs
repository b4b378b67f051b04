//! Errors: what was wrong and where.

use core::fmt;

/// Why a guide could not be built, configured or decoded.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A setting is outside its valid range.
    InvalidSetting {
        /// The setting's field name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What the value must satisfy.
        requirement: &'static str,
    },
    /// The byte budget cannot hold a single region of the requested resolution.
    BudgetTooSmall {
        /// The budget given, bytes.
        budget_bytes: usize,
        /// The bytes one region (plus fixed tables) needs.
        needed_bytes: usize,
    },
    /// The requested number of regions needs more memory than the budget.
    OverBudget {
        /// Regions requested.
        regions: usize,
        /// Bytes they need.
        needed_bytes: usize,
        /// The budget given, bytes.
        budget_bytes: usize,
    },
    /// The directional resolution exceeds the supported limit.
    ResolutionTooLarge {
        /// Entries per region requested.
        entries: u64,
        /// The largest supported count.
        limit: u32,
    },
    /// The triangles handed in have no finite, positive area to place probes on.
    NoSurface,
    /// A triangle has a coordinate that is NaN or infinite.
    NonFiniteTriangle {
        /// Its index in the slice handed in.
        index: usize,
    },
    /// A probe handed in is unusable.
    InvalidProbe {
        /// Its index.
        index: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// Two guides cannot be merged: they were not built over the same scene with the
    /// same settings.
    Incompatible {
        /// What differs (`settings`, `probes`).
        what: &'static str,
    },
    /// A serialized guide could not be read.
    Decode(DecodeError),
}

/// Why a serialized guide was rejected. Offsets are byte offsets into the buffer.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum DecodeError {
    /// The buffer ends before a field that should be there.
    Truncated {
        /// Byte offset of the field.
        offset: usize,
        /// Bytes the field needs.
        needed: usize,
        /// Bytes left at that offset.
        available: usize,
    },
    /// The buffer does not start with the Lodestar magic bytes.
    BadMagic,
    /// The format version is not one this build reads.
    UnsupportedVersion {
        /// Version in the buffer.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The buffer holds a different kind of guide.
    WrongStructure {
        /// Structure tag in the buffer.
        found: u32,
        /// Structure tag expected.
        expected: u32,
    },
    /// The checksum over the contents does not match: the buffer was altered or damaged.
    ChecksumMismatch {
        /// Checksum stored in the buffer.
        stored: u64,
        /// Checksum of the bytes read.
        computed: u64,
    },
    /// Bytes remain after the last field.
    TrailingBytes {
        /// How many.
        count: usize,
    },
    /// A field holds a value outside its valid range.
    InvalidField {
        /// The field's name.
        field: &'static str,
        /// Element index within the field (0 for scalars).
        index: usize,
        /// What the value must satisfy.
        requirement: &'static str,
    },
}

/// `Ok` when `ok`, else [`Error::InvalidSetting`] naming the setting: the check every
/// settings `validate` is made of.
#[cfg_attr(
    not(any(feature = "hemisphere", feature = "lights", feature = "env", feature = "mixture", feature = "volume")),
    allow(dead_code)
)]
pub(crate) fn require(ok: bool, name: &'static str, value: f64, requirement: &'static str) -> Result<(), Error> {
    if ok {
        Ok(())
    } else {
        Err(Error::InvalidSetting { name, value, requirement })
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidSetting { name, value, requirement } => {
                write!(f, "setting `{name}` = {value} is invalid: it must be {requirement}")
            }
            Error::BudgetTooSmall { budget_bytes, needed_bytes } => write!(
                f,
                "memory budget of {budget_bytes} bytes cannot hold one region: at least {needed_bytes} bytes are needed"
            ),
            Error::OverBudget { regions, needed_bytes, budget_bytes } => {
                write!(f, "{regions} regions need {needed_bytes} bytes, over the budget of {budget_bytes} bytes")
            }
            Error::ResolutionTooLarge { entries, limit } => {
                write!(f, "directional resolution of {entries} entries per region exceeds the limit of {limit}")
            }
            Error::NoSurface => write!(f, "no triangle with finite, positive area to place probes on"),
            Error::Incompatible { what } => {
                write!(
                    f,
                    "the guides' {what} differ: only guides built over the same scene with the same settings merge"
                )
            }
            Error::NonFiniteTriangle { index } => {
                write!(f, "triangle {index} has a NaN or infinite coordinate")
            }
            Error::InvalidProbe { index, reason } => write!(f, "probe {index} is invalid: {reason}"),
            Error::Decode(e) => write!(f, "cannot read serialized guide: {e}"),
        }
    }
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Truncated { offset, needed, available } => {
                write!(f, "truncated at byte {offset}: {needed} bytes needed, {available} left")
            }
            DecodeError::BadMagic => write!(f, "not a Lodestar guide (magic bytes missing)"),
            DecodeError::UnsupportedVersion { found, supported } => {
                write!(f, "format version {found} is not supported (this build reads {supported})")
            }
            DecodeError::WrongStructure { found, expected } => {
                write!(f, "holds guide structure {found}, expected {expected}")
            }
            DecodeError::ChecksumMismatch { stored, computed } => {
                write!(f, "checksum mismatch (stored {stored:#018x}, computed {computed:#018x}): the buffer is damaged")
            }
            DecodeError::TrailingBytes { count } => write!(f, "{count} unexpected bytes after the end"),
            DecodeError::InvalidField { field, index, requirement } => {
                write!(f, "field `{field}`[{index}] is invalid: it must be {requirement}")
            }
        }
    }
}

impl core::error::Error for Error {}
impl core::error::Error for DecodeError {}

impl From<DecodeError> for Error {
    fn from(e: DecodeError) -> Self {
        Error::Decode(e)
    }
}
