//! The directional structures a guide handle can hold, and how a C region maps to each
//! one's own region type. Every per-vertex call dispatches through [`with_structure!`].

use glam::Vec3;
use guiding_core::{
    DecodeError, Error, GaussianMixture, Guide, HemisphereGrid, IrradianceVolume, MixtureRegion, ProbeId,
    SpatialDirectionalTree, TreeRegion, VolumeRegion,
};

use crate::arguments::unit;
use crate::status::{Failure, LodestarStatus};
use crate::types::{LodestarRegion, LodestarVec3, LODESTAR_NO_REGION};

/// A region index checked below `count`; `LODESTAR_NO_REGION` and stale indices are
/// `INVALID_REGION` saying which.
fn region_index(index: u32, count: usize) -> Result<u32, Failure> {
    if (index as usize) < count {
        return Ok(index);
    }
    let why = if index == LODESTAR_NO_REGION {
        "LODESTAR_NO_REGION (locate found none: sample the BSDF alone)".to_string()
    } else {
        format!("past this guide's {count} regions")
    };
    Err(Failure::new(LodestarStatus::InvalidRegion, format!("`region.index` = {index} is {why}")))
}

/// The structures a handle can hold.
pub(crate) enum GuideStructure {
    Hemisphere(HemisphereGrid),
    Volume(IrradianceVolume),
    Mixture(GaussianMixture),
    Tree(SpatialDirectionalTree),
}

/// Runs `$body` with `$g` bound to the structure inside `$structure` (a reference to a
/// [`GuideStructure`], shared or mutable), whatever its type.
macro_rules! with_structure {
    ($structure:expr, $g:ident => $body:expr) => {
        match $structure {
            $crate::structure::GuideStructure::Hemisphere($g) => $body,
            $crate::structure::GuideStructure::Volume($g) => $body,
            $crate::structure::GuideStructure::Mixture($g) => $body,
            $crate::structure::GuideStructure::Tree($g) => $body,
        }
    };
}
pub(crate) use with_structure;

/// A guide the C ABI can hand regions out of and take them back into.
pub(crate) trait CRegions: Guide {
    /// How many regions an index may address.
    fn region_count(&self) -> usize;

    /// The C form of a located region.
    fn to_c(&self, region: Self::Region) -> LodestarRegion;

    /// The region a caller handed back; `index` is already checked against
    /// [`region_count`](Self::region_count).
    fn from_c(index: u32, flags: u32, normal: Vec3) -> Self::Region;

    /// A caller's region, checked against this guide.
    fn region(&self, region: LodestarRegion) -> Result<Self::Region, Failure> {
        region_index(region.index, self.region_count())?;
        let normal = Vec3::from(region.normal);
        let normal = normal.is_finite().then(|| unit(normal)).flatten().ok_or_else(|| {
            Failure::new(
                LodestarStatus::InvalidRegion,
                format!(
                    "`region.normal` = ({}, {}, {}) is not a direction: pass the region locate wrote",
                    normal.x, normal.y, normal.z
                ),
            )
        })?;
        Ok(Self::from_c(region.index, region.flags, normal))
    }
}

impl CRegions for HemisphereGrid {
    fn region_count(&self) -> usize {
        self.probe_count()
    }

    fn to_c(&self, region: ProbeId) -> LodestarRegion {
        // A probe's hemisphere has its own normal; the one handed in is not needed.
        LodestarRegion { index: region.0, flags: 0, normal: LodestarVec3 { x: 0.0, y: 0.0, z: 1.0 } }
    }

    fn from_c(index: u32, _: u32, _: Vec3) -> ProbeId {
        ProbeId(index)
    }

    fn region(&self, region: LodestarRegion) -> Result<ProbeId, Failure> {
        // The normal is not used: callers of the 0.1 ABI never filled it in.
        region_index(region.index, self.probe_count()).map(ProbeId)
    }
}

impl CRegions for IrradianceVolume {
    fn region_count(&self) -> usize {
        self.leaf_count()
    }

    fn to_c(&self, region: VolumeRegion) -> LodestarRegion {
        LodestarRegion { index: region.leaf, flags: 0, normal: region.normal.into() }
    }

    fn from_c(leaf: u32, _: u32, normal: Vec3) -> VolumeRegion {
        VolumeRegion { leaf, normal }
    }
}

impl CRegions for GaussianMixture {
    fn region_count(&self) -> usize {
        GaussianMixture::region_count(self)
    }

    fn to_c(&self, region: MixtureRegion) -> LodestarRegion {
        LodestarRegion { index: region.index, flags: 0, normal: region.normal.into() }
    }

    fn from_c(index: u32, _: u32, normal: Vec3) -> MixtureRegion {
        MixtureRegion { index, normal }
    }
}

/// `LodestarRegion.flags` bit of a tree region: the point lies in the upper half of its
/// leaf along the axis the leaf would split next.
const TREE_UPPER_HALF: u32 = 1;

impl CRegions for SpatialDirectionalTree {
    fn region_count(&self) -> usize {
        self.leaf_count()
    }

    fn to_c(&self, region: TreeRegion) -> LodestarRegion {
        let flags = if region.upper_half { TREE_UPPER_HALF } else { 0 };
        LodestarRegion { index: region.leaf, flags, normal: region.normal.into() }
    }

    fn from_c(leaf: u32, flags: u32, normal: Vec3) -> TreeRegion {
        TreeRegion { leaf, normal, upper_half: flags & TREE_UPPER_HALF != 0 }
    }
}

impl GuideStructure {
    /// Reads any directional structure's saved bytes: the first structure whose tag they
    /// carry decodes them.
    pub(crate) fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        let wrong = |e: &Error| matches!(e, Error::Decode(DecodeError::WrongStructure { .. }));
        let hemisphere = match HemisphereGrid::from_bytes(bytes) {
            Ok(grid) => return Ok(Self::Hemisphere(grid)),
            Err(e) if wrong(&e) => e,
            Err(e) => return Err(e),
        };
        match IrradianceVolume::from_bytes(bytes) {
            Ok(volume) => return Ok(Self::Volume(volume)),
            Err(e) if wrong(&e) => {}
            Err(e) => return Err(e),
        }
        match GaussianMixture::from_bytes(bytes) {
            Ok(mixture) => return Ok(Self::Mixture(mixture)),
            Err(e) if wrong(&e) => {}
            Err(e) => return Err(e),
        }
        match SpatialDirectionalTree::from_bytes(bytes) {
            Ok(tree) => Ok(Self::Tree(tree)),
            // None of the four: say what was found against the first one expected.
            Err(e) if wrong(&e) => Err(hemisphere),
            Err(e) => Err(e),
        }
    }
}
