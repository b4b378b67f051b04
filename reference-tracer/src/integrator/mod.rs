//! The path tracing integrators: `pt` (BSDF sampling), `nee` (plus next-event estimation
//! with MIS), `guided` (Dahm & Keller's Fig. 2E: sample the guide with probability
//! p_guide, else the BSDF, weighted by the one-sample MIS mixture pdf) and `guided-nee`
//! (both, with light samples MIS-weighted against the mixture), and `light` (light
//! tracing: paths from the area lights, each vertex connected to the camera), and `bdpt`
//! (bidirectional: every strategy joining a camera and a light subpath, weighted by
//! exact MIS). Guided
//! paths also learn: after each path every vertex with a guide region is updated by
//! Eq. (1).

mod bidirectional;
mod counters;
mod direct;
mod lanes;
mod light_path;
mod method;
mod path;
mod settings;
mod tracer;

pub use bidirectional::{BidirectionalScratch, VirtualPointLights};
pub use counters::{PathCounters, TIMED_PATH_STRIDE};
pub use lanes::LaneScratch;
pub use method::{EnvironmentSampling, LightSelection, Method};
pub use settings::{
    IntegratorSettings, Roulette, DEFAULT_CONNECTION_ROULETTE, DEFAULT_GUIDE_MIN_ALPHA, DEFAULT_LANES,
    DEFAULT_VPL_MIN_DISTANCE, DEFAULT_VPL_PATHS,
};
pub use tracer::{NeeRecords, PathScratch, PathTracer, VertexStrategies};
