//! Q(x, ω) in an adaptive spatial × directional tree (feature `tree`): a binary tree over
//! the scene's box whose leaves each hold a quadtree over the sphere's equal-area square,
//! refined together where paths land, learning from records of target/pdf (Müller et al.
//! 2017, "Practical Path Guiding", with the seed's targets of Eq. (1)).
//!
//! - [`SpatialDirectionalTree`]: the guide; [`SpatialDirectionalTreeSettings`]: its knobs.
//! - Sampling and the pdf descend the leaf's quadtree once each (the pdf twice where the
//!   distribution folds onto the normal's hemisphere); a record is one descent and one
//!   lock-free add.

mod guide;
mod quadtree;
mod serialize;
mod settings;
mod spatial;
mod square;

pub use guide::{SpatialDirectionalTree, TreeDistribution, TreeRegion};
pub use serialize::{FORMAT_VERSION, STRUCTURE_TAG};
pub use settings::{SpatialDirectionalTreeSettings, MAX_DIRECTIONAL_DEPTH, MAX_SPATIAL_DEPTH};
