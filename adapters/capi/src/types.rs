//! The plain C types that cross the boundary, and the library version.

use glam::Vec3;
use guiding_core::{GuideStats, UpdateOutcome};

use crate::status::{Failure, LodestarStatus};

/// Major version of this library: incompatible ABI changes bump it.
pub const LODESTAR_VERSION_MAJOR: u32 = 0;
/// Minor version: compatible additions.
pub const LODESTAR_VERSION_MINOR: u32 = 2;
/// Patch version: fixes.
pub const LODESTAR_VERSION_PATCH: u32 = 0;
/// `major·10000 + minor·100 + patch` of the header; compare with `lodestar_version`
/// to catch a header and a library that do not match.
pub const LODESTAR_VERSION: u32 =
    LODESTAR_VERSION_MAJOR * 10000 + LODESTAR_VERSION_MINOR * 100 + LODESTAR_VERSION_PATCH;

/// The version of the library linked, `major·10000 + minor·100 + patch`.
#[no_mangle]
pub extern "C" fn lodestar_version() -> u32 {
    LODESTAR_VERSION
}

/// A point (scene units) or a direction (world space).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LodestarVec3 {
    /// x
    pub x: f32,
    /// y
    pub y: f32,
    /// z
    pub z: f32,
}

impl From<LodestarVec3> for Vec3 {
    fn from(v: LodestarVec3) -> Self {
        Vec3::new(v.x, v.y, v.z)
    }
}

impl From<Vec3> for LodestarVec3 {
    fn from(v: Vec3) -> Self {
        Self { x: v.x, y: v.y, z: v.z }
    }
}

/// `LodestarRegion.index` when no region covers a point: sample the BSDF alone there.
pub const LODESTAR_NO_REGION: u32 = u32::MAX;

/// A located region of a guide, valid for the guide that returned it until that guide
/// is released or rebuilt into a new shape: pass it back as `locate` wrote it.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarRegion {
    /// The region's index (a probe, a leaf, a cell), or `LODESTAR_NO_REGION`.
    pub index: u32,
    /// Structure-private bits (the tree's half of a leaf); 0 for the others.
    pub flags: u32,
    /// The unit normal `locate` was given, which the volume, the mixture and the tree
    /// fold their directions about; the hemisphere grid uses its probe's own.
    pub normal: LodestarVec3,
}

/// A sampled direction and its density.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LodestarDirectionSample {
    /// Unit direction, world space.
    pub direction: LodestarVec3,
    /// Density of `direction`, per steradian; positive.
    pub pdf: f32,
}

/// How an accepted update call was taken. (NaN, infinite and negative targets are not
/// outcomes but errors: the call returns `LODESTAR_STATUS_NON_FINITE_ARGUMENT` or
/// `LODESTAR_STATUS_INVALID_ARGUMENT`, and the guide counts them in its stats.)
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LodestarUpdateOutcome {
    /// The target was blended into Q.
    Accepted = 0,
    /// The direction lies below the region's horizon: nothing to update.
    OutsideDomain = 1,
}

impl LodestarUpdateOutcome {
    /// The C outcome of a core update of `value` (named `name` in the message): the
    /// core's rejections become errors (NaN/∞: `NON_FINITE_ARGUMENT`, negative:
    /// `INVALID_ARGUMENT`), counted by the guide and not stored.
    pub(crate) fn from_core(outcome: UpdateOutcome, name: &str, value: f32) -> Result<Self, Failure> {
        match outcome {
            UpdateOutcome::Accepted => Ok(Self::Accepted),
            UpdateOutcome::OutsideDomain => Ok(Self::OutsideDomain),
            UpdateOutcome::RejectedNonFinite => Err(Failure::new(
                LodestarStatus::NonFiniteArgument,
                format!("`{name}` is {value}: rejected and counted, not stored"),
            )),
            UpdateOutcome::RejectedNegative => Err(Failure::new(
                LodestarStatus::InvalidArgument,
                format!("`{name}` = {value} is negative: rejected and counted, not stored"),
            )),
            other => Err(Failure::new(
                LodestarStatus::InternalError,
                format!("`{name}`: update outcome {other:?} has no C value yet"),
            )),
        }
    }
}

/// Sizes and counters of a guide.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LodestarGuideStats {
    /// Regions (probes).
    pub regions: u64,
    /// Directional entries (patches) per region.
    pub entries_per_region: u64,
    /// Bytes held by the guide's tables.
    pub memory_bytes: u64,
    /// Updates accepted since creation.
    pub accepted_updates: u64,
    /// Entries that received at least one update.
    pub visited_entries: u64,
    /// Targets rejected for being NaN or infinite.
    pub rejected_non_finite: u64,
    /// Targets rejected for being negative.
    pub rejected_negative: u64,
    /// Learning epochs completed (calls to `lodestar_guide_rebuild`).
    pub epochs: u32,
}

impl From<GuideStats> for LodestarGuideStats {
    fn from(s: GuideStats) -> Self {
        Self {
            regions: s.regions as u64,
            entries_per_region: s.entries_per_region as u64,
            memory_bytes: s.memory_bytes as u64,
            accepted_updates: s.accepted_updates,
            visited_entries: s.visited_entries as u64,
            rejected_non_finite: s.rejected_non_finite,
            rejected_negative: s.rejected_negative,
            epochs: s.epochs,
        }
    }
}
