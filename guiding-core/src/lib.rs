#![doc = include_str!("../README.md")]
#![no_std]
#![deny(missing_docs, unsafe_code)]

extern crate alloc;

mod efficiency_roulette;
// Shared by every guide structure; a build with none of them compiled in leaves them unused.
#[cfg(any(feature = "hemisphere", feature = "volume", feature = "tree"))]
mod atan2;
#[cfg_attr(
    not(any(
        feature = "hemisphere",
        feature = "lights",
        feature = "env",
        feature = "mixture",
        feature = "volume",
        feature = "tree",
        feature = "focal"
    )),
    allow(dead_code)
)]
mod atomic_f32;
#[cfg(any(feature = "lights", feature = "env"))]
mod average_records;
#[cfg_attr(
    not(any(feature = "hemisphere", feature = "mixture", feature = "volume", feature = "tree")),
    allow(dead_code)
)]
mod bytes;
pub mod cdf;
#[cfg(any(feature = "lights", feature = "env", feature = "mixture", feature = "volume"))]
mod cell_grid;
mod coarse_grid;
mod distribution;
mod error;
mod frame;
mod geometry;
mod guide;
mod intersector;
mod low_discrepancy;
mod path_recorder;
#[cfg(any(feature = "hemisphere", feature = "volume"))]
mod q_table;
mod scattering;
mod strategy_share;
#[cfg(any(feature = "hemisphere", feature = "volume"))]
mod table_checks;
mod update_rule;
pub mod validation;

#[cfg(feature = "env")]
pub mod environment;
#[cfg(feature = "focal")]
pub mod focal;
#[cfg(feature = "hemisphere")]
pub mod hemisphere;
#[cfg(feature = "lights")]
pub mod lights;
#[cfg(feature = "mixture")]
pub mod mixture;
#[cfg(feature = "tree")]
pub mod tree;
#[cfg(feature = "volume")]
pub mod volume;

/// The vector types of every signature here, re-exported so a renderer uses the same
/// version of glam as this crate.
pub use glam;

pub use bytes::reseal_checksum;
pub use distribution::{
    DirectionSample, DirectionalDistribution, UniformHemisphere, UniformSphere, MIN_SAMPLED_COS_THETA,
};
pub use efficiency_roulette::{
    EfficiencyRoulette, RouletteCell, RouletteImage, RouletteScale, MAX_SPLIT, MIN_SURVIVAL,
};
pub use error::{DecodeError, Error};
pub use frame::Frame;
pub use geometry::{square_to_triangle_barycentrics, Hit, Ray, Triangle};
pub use guide::{Guide, GuideStats};
pub use intersector::Intersector;
pub use low_discrepancy::{hammersley, radical_inverse_base2, Pcg32};
pub use path_recorder::{Onward, PathRecorder, RecordedVertex, Targets};
pub use scattering::{Lambertian, SampledDirection, ScatteringFunction};
pub use strategy_share::{StrategyArrival, StrategyShares};
pub use update_rule::{
    blend, classify_target, importance_weight, weighted_step, IntegralEstimator, LearningRate, UpdateOutcome,
    UpdateRule,
};

#[cfg(feature = "env")]
pub use environment::{EnvRecords, EnvTileGuide, EnvTileGuideSettings};
#[cfg(feature = "focal")]
pub use focal::{FocalArrival, FocalGuide, FocalGuideSettings, FocalRecord};
#[cfg(feature = "hemisphere")]
pub use hemisphere::{HemisphereGrid, HemisphereGridSettings, HemisphereMapping, PatchLayout, ProbeId, ProbeSet};
#[cfg(feature = "lights")]
pub use lights::{
    GateCell, LightCell, LightChoice, LightGuide, LightGuideSettings, LightRecords, LightUpdateRule, NextEventGate,
    NextEventGateSettings,
};
#[cfg(feature = "mixture")]
pub use mixture::{GaussianMixture, GaussianMixtureSettings, MixtureRegion};
#[cfg(feature = "tree")]
pub use tree::{
    FlatTree, SpatialDirectionalTree, SpatialDirectionalTreeSettings, TreeDistribution, TreeRecords, TreeRegion,
};
#[cfg(feature = "volume")]
pub use volume::{IrradianceVolume, IrradianceVolumeSettings, VolumeRegion};
