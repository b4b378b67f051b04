//! Learned environment sampling for next-event estimation (feature `env`): the
//! environment map cut into tiles, and per cell of a grid over the scene a learned
//! importance per tile (and per sun) from the light that actually arrived, so sky hidden
//! behind walls is learned away. The same learning as Dahm & Keller's Eq. (3) for lights.

mod guide;
pub mod lat_long;
mod records;
mod serialize;
mod settings;
mod sun;
mod tiles;

pub use guide::{EnvCell, EnvDistribution, EnvLobe, EnvSample, EnvTileGuide};
pub use records::EnvRecords;
pub use serialize::{FORMAT_VERSION as ENV_TILE_GUIDE_FORMAT_VERSION, STRUCTURE_TAG as ENV_TILE_GUIDE_TAG};
pub use settings::EnvTileGuideSettings;
pub use sun::SunDisk;
pub use tiles::{EnvironmentTiles, MAX_TEXELS};
