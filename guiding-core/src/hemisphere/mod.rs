//! The hemisphere grid (feature `hemisphere`): probes on the surfaces, each with a
//! hemisphere of equal-area patches holding Q.

mod candidate_table;
mod distribution;
mod grid;
mod mapping;
mod merge;
mod probe_lookup;
mod probes;
mod serialize;
mod settings;

pub use distribution::ProbeDistribution;
pub use grid::{HemisphereGrid, ProbeId};
pub use mapping::{HemisphereMapping, PatchLayout, MAX_PATCHES};
pub use probe_lookup::ProbeLookup;
pub use probes::ProbeSet;
pub use serialize::{FORMAT_VERSION, STRUCTURE_TAG};
pub use settings::{HemisphereGridSettings, DEFAULT_BUDGET_BYTES, MAX_PROBES};
