//! Rough plastic: a Lambertian base under a GGX dielectric coat (the model of Mitsuba's
//! `roughplastic` and Tungsten's `rough_plastic`). The coat reflects F(wo·h)·D·G2 /
//! (4 cos θo cos θi); light that enters through it, scatters off the base and leaves
//! again carries (1 − F(cos θi))(1 − F(cos θo)) / η² and the base's inter-reflections
//! under the coat, ρ / (1 − ρ·F_dr), per channel (Mitsuba's "nonlinear" form), with F_dr
//! the coat's hemispherical reflectance from inside. Local frame, z = normal facing the
//! viewer.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

use super::fresnel;
use super::microfacet::{distribution, reflection_pdf, sample_reflection, shadowing};
use super::BsdfSample;
use crate::color::luminance;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// The smallest coat roughness: smooth coats are approximated by this α.
pub const MIN_COAT_ALPHA: f32 = 1e-3;

/// A plastic's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plastic {
    /// Base reflectance in \[0, 1\]³.
    pub albedo: Vec3,
    /// Scale of the coat's reflection, in [0, 1].
    pub specular: f32,
    /// The coat's index of refraction (relative to the outside), > 1.
    pub ior: f32,
    /// The coat's GGX roughness α, ≥ [`MIN_COAT_ALPHA`].
    pub alpha: f32,
    /// The coat's hemispherical reflectance for light under it.
    pub internal_reflectance: f32,
}

impl Plastic {
    /// A plastic with the coat's internal reflectance computed.
    pub fn new(albedo: Vec3, specular: f32, ior: f32, alpha: f32) -> Self {
        let internal_reflectance = fresnel::diffuse_reflectance(1.0 / ior);
        Self { albedo, specular, ior, alpha: alpha.max(MIN_COAT_ALPHA), internal_reflectance }
    }

    fn specular_part(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize();
        let f = fresnel::dielectric(wo.dot(h).max(0.0), self.ior);
        self.specular * f * distribution(self.alpha, h) * shadowing(self.alpha, wo, wi) / (4.0 * wo.z)
    }

    fn diffuse_part(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let through = (1.0 - fresnel::dielectric(wi.z, self.ior)) * (1.0 - fresnel::dielectric(wo.z, self.ior));
        let base = self.albedo / (Vec3::ONE - self.albedo * self.internal_reflectance);
        base * (through * FRAC_1_PI * wi.z / (self.ior * self.ior))
    }

    /// Probability of sampling the coat rather than the base, seen from `wo`.
    pub(super) fn coat_probability(&self, wo: Vec3) -> f32 {
        let f = fresnel::dielectric(wo.z, self.ior);
        let base = luminance(self.albedo).max(0.0);
        let coat_weight = self.specular / (self.specular + base).max(f32::MIN_POSITIVE);
        let coat = f * coat_weight;
        let rest = (1.0 - f) * (1.0 - coat_weight);
        if coat + rest > 0.0 {
            coat / (coat + rest)
        } else {
            0.5
        }
    }

    /// `f(wo, wi)·cos θi`.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.diffuse_part(wo, wi) + Vec3::splat(self.specular_part(wo, wi))
    }

    /// Density of [`sample`](Self::sample) producing `wi`, per steradian.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let coat = self.coat_probability(wo);
        coat * reflection_pdf(self.alpha, wo, wi) + (1.0 - coat) * cosine_hemisphere_pdf(wi.z)
    }

    /// Picks the coat or the base by `u_lobe`, then a direction from it.
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = if u_lobe < self.coat_probability(wo) {
            sample_reflection(self.alpha, wo, u)?.0
        } else {
            cosine_hemisphere(u)
        };
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let weight = self.eval(wo, wi) / pdf;
        weight.is_finite().then_some(BsdfSample { wi, weight, pdf, delta: false })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use guiding_core::Pcg32;

    #[test]
    fn samples_match_eval_and_pdf_and_energy_stays_below_one() {
        let mut rng = Pcg32::new(3, 3);
        for (alpha, albedo) in [(0.05f32, 0.8f32), (0.3, 0.5), (0.001, 1.0), (0.8, 0.0)] {
            let plastic = Plastic::new(Vec3::splat(albedo), 1.0, 1.5, alpha);
            for cos in [1.0f32, 0.6, 0.15] {
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let n = 100_000;
                let mut total = 0.0f64;
                for _ in 0..n {
                    let Some(s) = plastic.sample(wo, rng.next_vec2(), rng.next_f32()) else { continue };
                    let expected = plastic.eval(wo, s.wi) / plastic.pdf(wo, s.wi);
                    assert!((s.weight - expected).abs().max_element() <= 1e-4 * expected.max_element().max(1.0));
                    total += s.weight.x as f64;
                }
                let reflectance = total / n as f64;
                assert!(reflectance <= 1.01, "α {alpha}, ρ {albedo}, cos {cos}: {reflectance}");
                // A white base under a coat loses little: most light comes back.
                if albedo == 1.0 && cos > 0.5 {
                    assert!(reflectance > 0.85, "α {alpha}, cos {cos}: {reflectance}");
                }
            }
        }
    }

    #[test]
    fn a_black_base_reflects_only_the_coat() {
        let plastic = Plastic::new(Vec3::ZERO, 1.0, 1.5, 0.2);
        let wo = Vec3::new(0.0, 0.0, 1.0);
        let wi = Vec3::new(0.6, 0.0, 0.8);
        assert!(plastic.eval(wo, wi).x > 0.0);
        assert_eq!(plastic.eval(wo, wi).x, plastic.eval(wo, wi).z);
        assert_eq!(plastic.eval(wo, -wi), Vec3::ZERO);
    }
}
