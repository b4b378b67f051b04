//! Lodestar's C ABI: `liblodestar` for C and C++ engines.
//!
//! Modelled on Open PGL's C API: an opaque `LodestarGuide` handle made by
//! `lodestar_guide_create` (or `lodestar_guide_load`) and freed by
//! `lodestar_guide_release`; per path vertex the renderer locates a region once, then
//! samples, evaluates pdfs and updates with it. Every call returns a `LodestarStatus`;
//! on failure `lodestar_last_error` says what was wrong and where. NULL pointers,
//! NaN/∞ inputs, wrong struct sizes, unknown enum values and damaged buffers are errors,
//! never crashes, and no Rust panic crosses the boundary.
//!
//! # Threads
//!
//! `locate`, `sample`, `pdf`, `update`, the `estimate_integral` calls, `stats`,
//! `validate`, `serialized_size`, `save` and a path recorder's `learn` are lock-free and
//! may run on one guide from any number of threads at once. `lodestar_guide_rebuild` and
//! `lodestar_guide_release` need the guide to themselves: no other call on the same
//! guide may be in flight (call `rebuild` between passes). A `LodestarPathRecorder`
//! belongs to one thread at a time. The error message is kept per thread.
//!
//! A `LodestarLightGuide` (learned light selection for next-event estimation, Eq. 3)
//! and a `LodestarEnvGuide` (learned environment sampling, per tile of the map and the
//! sun) follow the same rules: their per-vertex calls and `save` from any thread,
//! `rebuild` and `release` alone.
#![deny(missing_docs, unsafe_op_in_unsafe_fn)]

mod arguments;
mod bounded_guides;
mod config;
mod env_guide;
mod guide;
mod light_guide;
mod recorder;
mod serialize;
mod status;
mod structure;
mod types;

pub use bounded_guides::{
    lodestar_guide_create_mixture, lodestar_guide_create_tree, lodestar_guide_create_volume,
    lodestar_mixture_config_default, lodestar_tree_config_default, lodestar_volume_config_default,
    LodestarMixtureConfig, LodestarTreeConfig, LodestarVolumeConfig,
};
pub use config::{
    lodestar_guide_config_default, LodestarGuideConfig, LodestarIntegralEstimator, LodestarLearningRate,
    LodestarMapping, LodestarStructure,
};
pub use env_guide::{
    lodestar_env_guide_cell, lodestar_env_guide_config_default, lodestar_env_guide_create, lodestar_env_guide_load,
    lodestar_env_guide_merge, lodestar_env_guide_pdf, lodestar_env_guide_rebuild, lodestar_env_guide_release,
    lodestar_env_guide_reset, lodestar_env_guide_sample, lodestar_env_guide_save, lodestar_env_guide_update,
    LodestarEnvGuide, LodestarEnvGuideConfig, LodestarEnvSample, LodestarSunDisk,
};
pub use guide::{
    lodestar_guide_create, lodestar_guide_estimate_integral, lodestar_guide_estimate_integral_lambertian,
    lodestar_guide_locate, lodestar_guide_merge, lodestar_guide_pdf, lodestar_guide_rebuild, lodestar_guide_release,
    lodestar_guide_reset, lodestar_guide_sample, lodestar_guide_stats, lodestar_guide_structure, lodestar_guide_update,
    lodestar_guide_update_sampled, lodestar_guide_validate, LodestarEvalCos, LodestarGuide,
};
pub use light_guide::{
    lodestar_light_guide_cell, lodestar_light_guide_config_default, lodestar_light_guide_create,
    lodestar_light_guide_load, lodestar_light_guide_merge, lodestar_light_guide_probability,
    lodestar_light_guide_rebuild, lodestar_light_guide_release, lodestar_light_guide_reset, lodestar_light_guide_save,
    lodestar_light_guide_select, lodestar_light_guide_update, LodestarLightGuide, LodestarLightGuideConfig,
    LodestarLightRule,
};
pub use recorder::{
    lodestar_path_recorder_arrive, lodestar_path_recorder_carry, lodestar_path_recorder_clear,
    lodestar_path_recorder_create, lodestar_path_recorder_estimate, lodestar_path_recorder_learn,
    lodestar_path_recorder_reached, lodestar_path_recorder_release, lodestar_path_recorder_scattered,
    LodestarPathRecorder,
};
pub use serialize::{lodestar_guide_load, lodestar_guide_save, lodestar_guide_serialized_size};
pub use status::{lodestar_last_error, lodestar_status_name, LodestarStatus};
pub use types::{
    lodestar_version, LodestarDirectionSample, LodestarGuideStats, LodestarRegion, LodestarUpdateOutcome, LodestarVec3,
    LODESTAR_NO_REGION, LODESTAR_VERSION, LODESTAR_VERSION_MAJOR, LODESTAR_VERSION_MINOR, LODESTAR_VERSION_PATCH,
};
