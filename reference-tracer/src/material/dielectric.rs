//! Smooth dielectrics, both lobes delta: glass (exact unpolarised Fresnel reflection and
//! refraction) and a thin sheet (reflection including the sheet's inter-reflections,
//! the rest passing straight through). Local frame, z = the geometric normal (outside);
//! wo.z < 0 means inside.

use glam::Vec3;

use super::fresnel;
use super::BsdfSample;

pub(super) fn sample(ior: f32, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let entering = wo.z > 0.0;
    let eta = if entering { ior } else { 1.0 / ior };
    let cos_incident = wo.z.abs();
    let reflectance = fresnel::dielectric(cos_incident, eta);
    if u_lobe < reflectance {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        return Some(BsdfSample { wi, weight: Vec3::ONE, pdf: reflectance, delta: true });
    }
    let sin2_transmitted = (1.0 - cos_incident * cos_incident).max(0.0) / (eta * eta);
    let cos_transmitted = (1.0 - sin2_transmitted).max(0.0).sqrt();
    let wi = Vec3::new(-wo.x / eta, -wo.y / eta, if entering { -cos_transmitted } else { cos_transmitted });
    // Radiance is compressed into the denser medium: L_t = L_i / η².
    let weight = Vec3::splat(1.0 / (eta * eta));
    Some(BsdfSample { wi: wi.normalize(), weight, pdf: 1.0 - reflectance, delta: true })
}

/// A thin sheet: one interface reflects R = F(cos θ); light bouncing inside the sheet
/// adds T²R/(1 − R²), so the sheet reflects 2R/(1 + R) and transmits the rest, leaving
/// in the direction it came (the two refractions cancel).
pub(super) fn sample_thin(ior: f32, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let r = fresnel::dielectric(wo.z.abs(), ior);
    let reflectance = 2.0 * r / (1.0 + r);
    if u_lobe < reflectance {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        return Some(BsdfSample { wi, weight: Vec3::ONE, pdf: reflectance, delta: true });
    }
    Some(BsdfSample { wi: -wo, weight: Vec3::ONE, pdf: 1.0 - reflectance, delta: true })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_obeys_snell() {
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let s = sample(1.5, wo, 0.99).unwrap();
        assert!(s.wi.z < 0.0);
        let sin_i = 0.6;
        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-5);
    }

    #[test]
    fn a_thin_sheet_passes_light_straight_through_and_reflects_more_than_one_face() {
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let through = sample_thin(1.5, wo, 0.999).unwrap();
        assert_eq!(through.wi, -wo);
        let reflected = sample_thin(1.5, wo, 0.0).unwrap();
        let r = fresnel::dielectric(0.8, 1.5);
        assert!(reflected.pdf > r && reflected.pdf < 2.0 * r);
        assert!((reflected.pdf + through.pdf - 1.0).abs() < 1e-6);
        // From the other side alike.
        assert_eq!(sample_thin(1.5, -wo, 0.999).unwrap().wi, wo);
    }
}
