//! The GGX (Trowbridge–Reitz) microfacet distribution with height-correlated Smith
//! shadowing, sampled from its distribution of visible normals (Heitz 2018). Local
//! frame, z = the macro-surface normal facing the viewer; α is the roughness (not squared).

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// Roughness below which a non-zero α is treated as this, to keep D finite in f32.
pub const MIN_ALPHA: f32 = 1e-4;

/// D(h): the density of micro-normals, per steradian of h, projected.
pub fn distribution(alpha: f32, h: Vec3) -> f32 {
    let a2 = alpha * alpha;
    let d = h.z * h.z * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Smith's Λ for GGX.
pub fn lambda(alpha: f32, w: Vec3) -> f32 {
    let cos2 = w.z * w.z;
    if cos2 <= 0.0 {
        return f32::INFINITY;
    }
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Height-correlated masking-shadowing G2(wo, wi).
pub fn shadowing(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    1.0 / (1.0 + lambda(alpha, wo) + lambda(alpha, wi))
}

/// Density of `wi = reflect(wo, h)` when h is drawn from the visible normals of `wo`:
/// D_wo(h) / (4 wo·h) = G1(wo) D(h) / (4 cos θo). Zero below either horizon.
pub fn reflection_pdf(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    let g1 = 1.0 / (1.0 + lambda(alpha, wo));
    g1 * distribution(alpha, h) / (4.0 * wo.z)
}

/// Draws a micro-normal from the visible normals of `wo` (wo.z > 0) and reflects `wo`
/// about it; `None` when the reflection falls below the horizon.
pub fn sample_reflection(alpha: f32, wo: Vec3, u: Vec2) -> Option<(Vec3, Vec3)> {
    // Stretch, sample the projected disk, unstretch.
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let length2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if length2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / length2.sqrt() } else { Vec3::X };
    let t2 = vh.cross(t1);
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let h = Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-6)).normalize();
    let wi = 2.0 * wo.dot(h) * h - wo;
    (wi.z > 0.0).then_some((wi, h))
}
