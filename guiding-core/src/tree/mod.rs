//! Q(x, ω) in an adaptive spatial × directional tree (feature `tree`): a binary tree over
//! the scene's box whose leaves each hold a quadtree over the sphere's equal-area square,
//! refined together where paths land, learning from records of target/pdf (Müller et al.
//! 2017, "Practical Path Guiding", with the seed's targets of Eq. (1)).
//!
//! - [`SpatialDirectionalTree`]: the guide; [`SpatialDirectionalTreeSettings`]: its knobs.
//! - Each leaf's square is built around the world axis its records' normals lie along:
//!   for such a normal, sampling and the pdf descend the leaf's quadtree once each, in
//!   the half of the square above the surface; for other normals the sphere folds onto
//!   the hemisphere (the pdf descends twice). A record is one descent and lock-free adds,
//!   or, through a thread's own [`TreeRecords`], an append learned between passes.
//! - Where the normal lies along the axis, the half is sampled by the tree's density
//!   times cos θ (the settings' `cosine_product`), from a second set of cell
//!   probabilities computed at each refit.

mod axis;
mod cosine;
mod distribution;
mod flat;
mod guide;
mod merge;
mod quadtree;
mod records;
mod serialize;
mod settings;
mod spatial;
mod square;
mod top_grid;

pub use distribution::TreeDistribution;
pub use flat::FlatTree;
pub use guide::{SpatialDirectionalTree, TreeRegion};
pub use records::TreeRecords;
pub use serialize::{FORMAT_VERSION, STRUCTURE_TAG};
pub use settings::{SpatialDirectionalTreeSettings, MAX_DIRECTIONAL_DEPTH, MAX_SPATIAL_DEPTH};
