//! A vertex of a camera or light subpath, and which side's sampling a density is of.

use glam::Vec3;

use crate::material::{Material, ShadingFrame};

/// What a subpath vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum VertexKind {
    /// The pinhole.
    Camera,
    /// A point on an area light, where a light subpath starts.
    Light,
    /// A surface a subpath reached.
    Surface,
}

/// One vertex of a camera or light subpath; `R` is the directional guide's region type.
#[derive(Clone, Copy, Debug)]
pub struct SubpathVertex<R> {
    pub(super) kind: VertexKind,
    pub(super) point: Vec3,
    /// The geometric normal (a light's emitting side; unused at the camera).
    pub(super) normal: Vec3,
    /// Unit direction to the previous vertex of its own subpath (surfaces).
    pub(super) wo: Vec3,
    /// A surface's material and shading frame (seen from `wo`).
    pub(super) surface: Option<(Material, ShadingFrame)>,
    /// The light it lies on (light vertices, and emitters a camera subpath reached).
    pub(super) light: Option<u32>,
    /// The subpath's throughput up to this vertex: radiance weight from the camera,
    /// power weight from the light (emitted radiance over the densities so far).
    pub(super) beta: Vec3,
    /// Density per unit area (at this vertex) with which its own subpath reached it.
    pub(super) pdf_fwd: f32,
    /// Density per unit area with which the other subpath's sampling would reach it
    /// from the next vertex of its own subpath.
    pub(super) pdf_rev: f32,
    /// Whether every lobe of the surface here is a delta (mirrors, glass): its sampled
    /// direction has no density and no connection ends here.
    pub(super) delta: bool,
    /// bdpt-guided: Q's region here (surfaces whose lobes are not all delta), which the
    /// camera side's sampling mixes in.
    pub(super) region: Option<R>,
    /// bdpt-guided: W's region here (the same surfaces, and light origins), which the
    /// light side's sampling mixes in.
    pub(super) importance_region: Option<R>,
    /// Density per steradian of the direction sampled here (what the guide learns with).
    pub(super) scatter_pdf: f32,
    /// bdpt-guided: the other side's guide density per steradian here towards the
    /// previous vertex of this subpath (W's on the camera side, Q's on the light side),
    /// where that side guides here. The walk needs it for the previous vertex's reverse
    /// density, and every connection at this vertex again: computed once.
    pub(super) back_guide_pdf: Option<f32>,
}

impl<R: Copy> SubpathVertex<R> {
    pub(super) fn new(kind: VertexKind, point: Vec3, normal: Vec3, beta: Vec3, pdf_fwd: f32) -> Self {
        Self {
            kind,
            point,
            normal,
            wo: Vec3::ZERO,
            surface: None,
            light: None,
            beta,
            pdf_fwd,
            pdf_rev: 0.0,
            delta: false,
            region: None,
            importance_region: None,
            scatter_pdf: 0.0,
            back_guide_pdf: None,
        }
    }

    /// A density per steradian of leaving this vertex towards `next`, as a density per
    /// unit area at `next` (the cosine there, except at the camera, which is no surface).
    pub(super) fn area_density(&self, pdf_dir: f32, next: &SubpathVertex<R>) -> f32 {
        let offset = next.point - self.point;
        let distance2 = offset.length_squared();
        if !distance2.is_finite() || distance2 <= 0.0 {
            return 0.0;
        }
        let mut pdf = pdf_dir / distance2;
        if next.kind != VertexKind::Camera {
            pdf *= (next.normal.dot(offset) / distance2.sqrt()).abs();
        }
        pdf
    }

    /// The radiance a camera subpath's emitter sends back along `wo` (zero elsewhere).
    pub(super) fn emitted(&self) -> Vec3 {
        match self.surface {
            Some((material, _)) if self.normal.dot(self.wo) > 0.0 => material.emission,
            _ => Vec3::ZERO,
        }
    }
}

/// Which subpath's sampling a density is of: the camera's (guided in bdpt-guided) or
/// the light's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Side {
    Camera,
    Light,
}

impl Side {
    pub(super) fn other(self) -> Side {
        match self {
            Side::Camera => Side::Light,
            Side::Light => Side::Camera,
        }
    }
}
