//! GGX microfacet reflection with height-correlated Smith shadowing, sampled from the
//! distribution of visible normals (Heitz 2018). The `specular` colour scales it; with a
//! complex index of refraction the Fresnel term F(wo·h) multiplies it too, else there is
//! none. Local frame, z = normal facing the viewer.

use glam::{Vec2, Vec3};

use super::fresnel::{self, ComplexIor};
use super::microfacet::{distribution, lambda, reflection_pdf, sample_reflection, shadowing, MIN_ALPHA};
use super::BsdfSample;

fn mirror(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

fn fresnel_term(ior: Option<&ComplexIor>, cos: f32) -> Vec3 {
    ior.map_or(Vec3::ONE, |ior| fresnel::conductor(cos, ior))
}

pub(super) fn eval(specular: Vec3, alpha: f32, ior: Option<&ComplexIor>, wo: Vec3, wi: Vec3) -> Vec3 {
    if alpha == 0.0 || wo.z <= 0.0 || wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    let alpha = alpha.max(MIN_ALPHA);
    let h = (wo + wi).normalize();
    // f·cos θi = F D G2 / (4 cos θo cos θi) · cos θi
    specular * fresnel_term(ior, wo.dot(h)) * (distribution(alpha, h) * shadowing(alpha, wo, wi) / (4.0 * wo.z))
}

pub(super) fn pdf(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    if alpha == 0.0 {
        return 0.0;
    }
    reflection_pdf(alpha.max(MIN_ALPHA), wo, wi)
}

pub(super) fn sample(specular: Vec3, alpha: f32, ior: Option<&ComplexIor>, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
    if wo.z <= 0.0 {
        return None;
    }
    if alpha == 0.0 {
        return Some(BsdfSample { wi: mirror(wo), weight: specular * fresnel_term(ior, wo.z), pdf: 1.0, delta: true });
    }
    let alpha = alpha.max(MIN_ALPHA);
    let (wi, h) = sample_reflection(alpha, wo, u)?;
    let pdf = reflection_pdf(alpha, wo, wi);
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    // eval / pdf = F · specular · G2 / G1(wo)
    let shadow_ratio = (1.0 + lambda(alpha, wo)) / (1.0 + lambda(alpha, wo) + lambda(alpha, wi));
    let weight = specular * fresnel_term(ior, wo.dot(h)) * shadow_ratio;
    Some(BsdfSample { wi, weight, pdf, delta: false })
}

#[cfg(test)]
mod tests {
    use super::*;
    use guiding_core::Pcg32;
    use std::f32::consts::PI;

    /// Sampled weights equal eval/pdf, and the pdf integrates to (at most) one over the
    /// upper hemisphere: E_uniform[pdf]·2π ≈ 1 minus the mass sampled below the horizon.
    #[test]
    fn sampling_matches_eval_and_pdf() {
        let mut rng = Pcg32::new(7, 7);
        for alpha in [0.05f32, 0.3, 0.8] {
            let wo = Vec3::new(0.4, -0.2, 0.9).normalize();
            for _ in 0..2000 {
                let Some(s) = sample(Vec3::ONE, alpha, None, wo, rng.next_vec2()) else { continue };
                let expected = eval(Vec3::ONE, alpha, None, wo, s.wi) / pdf(alpha, wo, s.wi);
                assert!((s.weight - expected).abs().max_element() < 1e-3 * expected.max_element().max(1.0));
                assert!((pdf(alpha, wo, s.wi) - s.pdf).abs() <= 1e-4 * s.pdf);
            }
            // The pdf's mass over the upper hemisphere is the share of samples that stay
            // above the horizon.
            let n = 400_000;
            let kept = (0..n).filter(|_| sample(Vec3::ONE, alpha, None, wo, rng.next_vec2()).is_some()).count();
            let kept_share = kept as f64 / n as f64;
            let mut integral = 0.0f64;
            for _ in 0..n {
                let u = rng.next_vec2();
                let z = u.x;
                let r = (1.0 - z * z).sqrt();
                let wi = Vec3::new(r * (2.0 * PI * u.y).cos(), r * (2.0 * PI * u.y).sin(), z);
                integral += pdf(alpha, wo, wi) as f64 * 2.0 * std::f64::consts::PI;
            }
            integral /= n as f64;
            // Uniform directions estimate a peaked pdf poorly: allow more for small α.
            let tolerance = if alpha < 0.1 { 0.05 } else { 0.01 };
            assert!((integral - kept_share).abs() < tolerance, "α = {alpha}: ∫pdf = {integral}, kept {kept_share}");
        }
    }

    #[test]
    fn a_white_rough_conductor_does_not_create_energy() {
        // Albedo = E[weight] over samples (lost samples count as zero) stays ≤ 1.
        let mut rng = Pcg32::new(8, 8);
        for alpha in [0.1f32, 0.5, 1.0] {
            for cos in [1.0f32, 0.5, 0.1] {
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let n = 100_000;
                let total: f32 = (0..n)
                    .filter_map(|_| sample(Vec3::ONE, alpha, None, wo, rng.next_vec2()))
                    .map(|s| s.weight.x)
                    .sum();
                let albedo = total / n as f32;
                assert!(albedo <= 1.001 && albedo > 0.3, "α = {alpha}, cos = {cos}: albedo {albedo}");
            }
        }
    }
}
