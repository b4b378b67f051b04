//! Focal guiding (feature `focal`): a density over space, learned from the path segments
//! that carried light, whose dense spots (a door's gap, a keyhole, a lens's focus) the
//! sampler aims at from wherever a vertex is (after Rath et al. 2023, "Focal Path Guiding
//! for Light Transport Simulation").
//!
//! A directional guide stores, per region, where light came from; where it all squeezes
//! through one small opening, the opening's direction changes across a region (parallax),
//! so each region's lobe is as wide as the region is seen from the opening. A point in
//! space has no parallax: drawing a point y from the learned density and shooting
//! towards it aims through the gap from every vertex alike.
//!
//! - The octree (`FocalOctree`) learns: each recorded segment adds its weight × length to
//!   the leaves it crosses (at stratified points along it); leaves that gather more than
//!   a share of the mass split in eight.
//! - [`FocalGuide`] samples: the densest leaves (mass per volume well above the mean of
//!   the occupied space) become a small set of boxes chosen by mass; a direction's pdf is
//!   the exact line integral of the boxes' density, ∫ ρ(x + tω) t² dt. Neighbouring
//!   leaves of like density merge first, so a long thin opening is a few
//!   long boxes, not a row of many cubes.
//! - Each cell of a coarse grid learns which boxes its vertices' light actually came
//!   through (`BoxCells`): from behind a wall, boxes out of sight through the gap are
//!   drawn less often there.
//! - Boxes can also be given (`KnownBox`): a light's mirror image behind a flat mirror is
//!   a focal spot no segment passes through, which the octree cannot learn.

mod box_cells;
mod guide;
mod known_boxes;
mod lanes;
mod merge;
mod octree;
mod settings;

pub use guide::{FocalArrival, FocalBox, FocalGuide, FocalRecord, CANDIDATES};
pub use known_boxes::{KnownBox, MAX_KNOWN_BOXES};
pub use settings::{FocalGuideSettings, MAX_FOCAL_DEPTH};
