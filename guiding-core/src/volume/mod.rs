//! Q in an irradiance volume (feature `volume`): full-sphere tables of equal-area patches
//! at the leaves of an octree over the scene, found by position, split where updates
//! concentrate until the byte budget is spent.

mod distribution;
mod guide;
mod irradiance_sh;
mod merge;
mod serialize;
mod settings;
mod sphere_layout;

pub use distribution::VolumeDistribution;
pub use guide::{IrradianceVolume, VolumeRegion};
pub use irradiance_sh::SH_NORMALIZATION;
pub use settings::IrradianceVolumeSettings;
pub use sphere_layout::SphereLayout;
