//! Fresnel reflectance: dielectric interfaces, conductors with a complex index of
//! refraction, and the hemispherical average a diffuse layer under a coat sees.

use glam::Vec3;

/// Unpolarised Fresnel reflectance for cos θ (≥ 0) on the incident side and relative
/// index η = n_transmitted / n_incident; 1 under total internal reflection.
pub fn dielectric(cos_incident: f32, eta: f32) -> f32 {
    let sin2_transmitted = (1.0 - cos_incident * cos_incident).max(0.0) / (eta * eta);
    if sin2_transmitted >= 1.0 {
        return 1.0;
    }
    let cos_transmitted = (1.0 - sin2_transmitted).sqrt();
    let parallel = (eta * cos_incident - cos_transmitted) / (eta * cos_incident + cos_transmitted);
    let perpendicular = (cos_incident - eta * cos_transmitted) / (cos_incident + eta * cos_transmitted);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

/// A conductor's complex index of refraction η + i·k relative to the outside, per RGB
/// channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComplexIor {
    /// Real part.
    pub eta: Vec3,
    /// Imaginary part (absorption).
    pub k: Vec3,
}

/// Unpolarised Fresnel reflectance of a conductor for cos θ in [0, 1], per channel
/// (the exact expression for a complex index, as in pbrt's `FrConductor`).
pub fn conductor(cos_incident: f32, ior: &ComplexIor) -> Vec3 {
    let cos = cos_incident.clamp(0.0, 1.0);
    let cos2 = Vec3::splat(cos * cos);
    let sin2 = Vec3::ONE - cos2;
    let eta2 = ior.eta * ior.eta;
    let k2 = ior.k * ior.k;
    let t0 = eta2 - k2 - sin2;
    let a2_plus_b2 = (t0 * t0 + 4.0 * eta2 * k2).max(Vec3::ZERO).powf(0.5);
    let t1 = a2_plus_b2 + cos2;
    let a = (0.5 * (a2_plus_b2 + t0)).max(Vec3::ZERO).powf(0.5);
    let t2 = 2.0 * cos * a;
    let perpendicular = (t1 - t2) / (t1 + t2).max(Vec3::splat(f32::MIN_POSITIVE));
    let t3 = cos2 * a2_plus_b2 + sin2 * sin2;
    let t4 = t2 * sin2;
    let parallel = perpendicular * (t3 - t4) / (t3 + t4).max(Vec3::splat(f32::MIN_POSITIVE));
    (0.5 * (parallel + perpendicular)).clamp(Vec3::ZERO, Vec3::ONE)
}

/// ∫ F(cos θ, η) 2 cos θ sin θ dθ over the hemisphere: the share of uniformly diffuse
/// light that an interface of relative index `eta` reflects (for light inside a coat,
/// η = 1/ior, total internal reflection included). Midpoint rule in cos θ.
pub fn diffuse_reflectance(eta: f32) -> f32 {
    let steps = 4096;
    let sum: f64 = (0..steps)
        .map(|i| {
            let mu = (i as f32 + 0.5) / steps as f32;
            dielectric(mu, eta) as f64 * 2.0 * mu as f64
        })
        .sum();
    (sum / steps as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_limits() {
        let normal = ((1.5f32 - 1.0) / (1.5 + 1.0)).powi(2);
        assert!((dielectric(1.0, 1.5) - normal).abs() < 1e-6);
        assert!((dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(dielectric(0.1, 1.0 / 1.5), 1.0, "total internal reflection");
    }

    #[test]
    fn conductor_matches_its_limits() {
        // k = 0 reduces to the dielectric expression; normal incidence has a closed form.
        let glass = ComplexIor { eta: Vec3::splat(1.5), k: Vec3::ZERO };
        for cos in [1.0f32, 0.7, 0.3, 0.05] {
            let f = conductor(cos, &glass);
            assert!((f.x - dielectric(cos, 1.5)).abs() < 1e-4, "cos {cos}: {f} vs {}", dielectric(cos, 1.5));
        }
        let gold = ComplexIor { eta: Vec3::new(0.143, 0.374, 1.442), k: Vec3::new(3.983, 2.385, 1.603) };
        let f = conductor(1.0, &gold);
        let normal = ((gold.eta - 1.0).powf(2.0) + gold.k * gold.k) / ((gold.eta + 1.0).powf(2.0) + gold.k * gold.k);
        assert!((f - normal).abs().max_element() < 1e-4, "{f} vs {normal}");
        assert!((conductor(0.0, &gold) - Vec3::ONE).abs().max_element() < 1e-4, "grazing");
    }

    #[test]
    fn diffuse_reflectance_of_glass() {
        // Known values: about 0.092 from outside (η = 1.5), about 0.596 from inside.
        assert!((diffuse_reflectance(1.5) - 0.092).abs() < 0.003, "{}", diffuse_reflectance(1.5));
        assert!((diffuse_reflectance(1.0 / 1.5) - 0.596).abs() < 0.003, "{}", diffuse_reflectance(1.0 / 1.5));
    }
}
