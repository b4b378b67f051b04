//! Learned light selection for next-event estimation (feature `lights`): Dahm & Keller's
//! Eq. (3), V'(c,l) = (1-α)·V(c,l) + α·‖C_l(x)‖∞, per cell c of a regular grid over the
//! scene and light l, mixed with a power-proportional and a uniform defensive share so no
//! light ever has probability zero. Beside it, [`NextEventGate`]: per cell, whether to
//! shoot a shadow ray at all.

mod gate;
mod guide;
mod records;
mod serialize;
mod settings;

pub use gate::{GateCell, NextEventGate, NextEventGateSettings};
pub use guide::{LightCell, LightChoice, LightGuide};
pub use records::LightRecords;
pub use serialize::{FORMAT_VERSION as LIGHT_GUIDE_FORMAT_VERSION, STRUCTURE_TAG as LIGHT_GUIDE_TAG};
pub use settings::{LightGuideSettings, LightUpdateRule};
