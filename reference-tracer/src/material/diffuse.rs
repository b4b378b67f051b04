//! Lambertian reflection (local frame, z = normal facing the viewer).

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

use super::BsdfSample;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

pub(super) fn eval(albedo: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    albedo * FRAC_1_PI * wi.z
}

pub(super) fn pdf(wo: Vec3, wi: Vec3) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    cosine_hemisphere_pdf(wi.z)
}

pub(super) fn sample(albedo: Vec3, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
    if wo.z <= 0.0 {
        return None;
    }
    let wi = cosine_hemisphere(u);
    let pdf = cosine_hemisphere_pdf(wi.z);
    (pdf > 0.0).then_some(BsdfSample { wi, weight: albedo, pdf, delta: false })
}
