//! The uniform block the shader reads (`shader/header.wgsl`'s `Params`) and the codes its
//! fields carry for the method, the guide structure and the learning rate.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use guiding_core::LearningRate;

use crate::integrator::Method;

/// The uniform block of the shader (`shader/header.wgsl`'s `Params`).
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
pub(super) struct Params {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) pass_index: u32,
    pub(super) seed: u32,
    pub(super) max_depth: u32,
    pub(super) rr_depth: u32,
    pub(super) method: u32,
    pub(super) light_count: u32,
    pub(super) eye: [f32; 4],
    pub(super) forward: [f32; 4],
    pub(super) right: [f32; 4],
    pub(super) up: [f32; 4],
    pub(super) environment: [f32; 4],
    pub(super) scene: [f32; 4],
    pub(super) guide: [u32; 4],
    pub(super) guide_shape: [u32; 4],
    pub(super) guide_lookup: [f32; 4],
    pub(super) guide_rule: [f32; 4],
    pub(super) volume_grid: [u32; 4],
    pub(super) volume_low: [f32; 4],
    pub(super) volume_scale: [f32; 4],
    pub(super) sample_normal: [f32; 4],
}

impl Params {
    /// The guide `kind` (GUIDE_*) and its grid of cells: cells per axis, low corner and
    /// cells per unit length.
    pub(super) fn set_cell_grid(&mut self, kind: u32, [x, y, z]: [u32; 3], (low, inverse_cell_size): (Vec3, Vec3)) {
        self.volume_grid = [x, y, z, kind];
        self.volume_low = low.extend(0.0).to_array();
        self.volume_scale = inverse_cell_size.extend(0.0).to_array();
    }
}

/// `Params::volume_grid[3]`: which structure guides (the shader's GUIDE_*).
pub(super) const GUIDE_HEMISPHERE: u32 = 0;
pub(super) const GUIDE_VOLUME: u32 = 1;
pub(super) const GUIDE_MIXTURE: u32 = 2;

pub(super) fn learning_rate_code(rate: LearningRate) -> (f32, f32) {
    match rate {
        LearningRate::Exponential { alpha } => (0.0, alpha),
        LearningRate::SimpleAverage => (1.0, 0.0),
        LearningRate::RegionVisits => (2.0, 0.0),
        LearningRate::Global { .. } => (1.0, 0.0),
        other => unreachable!("{other:?} has no shader code yet"),
    }
}

pub(super) fn method_code(method: Method) -> u32 {
    match method {
        Method::Pt => 0,
        Method::Nee => 1,
        Method::Guided => 2,
        Method::GuidedNee => 3,
        // Refused before the GPU is reached (`Prepared::render`).
        Method::Light | Method::LightGuided | Method::Bdpt | Method::BdptGuided | Method::Vpl | Method::VplGuided => {
            unreachable!("the GPU tracer has no light subpaths")
        }
    }
}
