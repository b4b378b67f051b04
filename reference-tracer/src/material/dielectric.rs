//! Smooth dielectric: exact unpolarised Fresnel reflection and refraction, both delta
//! lobes. Local frame, z = the geometric normal (outside); wo.z < 0 means inside.

use glam::Vec3;

use super::BsdfSample;

/// Unpolarised Fresnel reflectance for cos θ (≥ 0) on the incident side and relative
/// index η = n_transmitted / n_incident; 1 under total internal reflection.
pub fn fresnel_reflectance(cos_incident: f32, eta: f32) -> f32 {
    let sin2_transmitted = (1.0 - cos_incident * cos_incident).max(0.0) / (eta * eta);
    if sin2_transmitted >= 1.0 {
        return 1.0;
    }
    let cos_transmitted = (1.0 - sin2_transmitted).sqrt();
    let parallel = (eta * cos_incident - cos_transmitted) / (eta * cos_incident + cos_transmitted);
    let perpendicular = (cos_incident - eta * cos_transmitted) / (cos_incident + eta * cos_transmitted);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

pub(super) fn sample(ior: f32, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let entering = wo.z > 0.0;
    let eta = if entering { ior } else { 1.0 / ior };
    let cos_incident = wo.z.abs();
    let reflectance = fresnel_reflectance(cos_incident, eta);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        let normal = ((1.5f32 - 1.0) / (1.5 + 1.0)).powi(2);
        assert!((fresnel_reflectance(1.0, 1.5) - normal).abs() < 1e-6);
        assert!((fresnel_reflectance(0.0, 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(fresnel_reflectance(0.1, 1.0 / 1.5), 1.0, "total internal reflection");
    }

    #[test]
    fn refraction_obeys_snell() {
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let s = sample(1.5, wo, 0.99).unwrap();
        assert!(s.wi.z < 0.0);
        let sin_i = 0.6;
        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-5);
    }
}
