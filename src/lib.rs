//! Lodestar: path guiding by reinforcement learning.
//!
//! This package gathers the workspace's crates under one name and owns the
//! workspace-wide property tests (`tests/`) and benchmarks (`benches/`).
//! [`guiding_core`] is the `no_std` heart a renderer links.
#![no_std]
#![deny(missing_docs)]

pub use guiding_core;
