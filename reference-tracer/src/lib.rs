//! # reference-tracer
//!
//! Lodestar's reference CPU path tracer: it reads a scene (SCENE_FORMAT.md), builds an
//! obvhs intersector, traces paths unguided (`pt`, `nee`) or guided (`guided`,
//! `guided-nee`) by any of guiding-core's Q structures — the
//! [`HemisphereGrid`](guiding_core::HemisphereGrid) or the
//! [`GaussianMixture`](guiding_core::GaussianMixture) — learns while it renders, and
//! reports images, statistics and error against run time.
//!
//! The data path runs one way: scene → intersector → integrator → guide → image.

pub mod animation;
pub mod backend;
pub mod camera;
pub mod cli;
pub mod color;
pub mod directional_guide;
pub mod environment;
pub mod film;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod image_estimates;
pub mod import;
pub mod integrator;
pub mod learners;
pub mod lights;
pub mod material;
pub mod metrics;
pub mod mirror_images;
pub mod output;
pub mod peer;
pub mod plan;
pub mod render;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod scene_intersector;
pub mod schedule;
pub mod session;
pub mod texture;
