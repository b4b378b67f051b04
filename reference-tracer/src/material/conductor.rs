//! GGX microfacet reflection with height-correlated Smith shadowing and no Fresnel term
//! (the `specular` colour scales it), sampled from the distribution of visible normals
//! (Heitz 2018). Local frame, z = normal facing the viewer.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::BsdfSample;

/// Roughness below which a non-zero α is treated as this, to keep D finite in f32.
const MIN_ALPHA: f32 = 1e-4;

fn distribution(alpha: f32, h: Vec3) -> f32 {
    let a2 = alpha * alpha;
    let d = h.z * h.z * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Smith's Λ for GGX.
fn lambda(alpha: f32, w: Vec3) -> f32 {
    let cos2 = w.z * w.z;
    if cos2 <= 0.0 {
        return f32::INFINITY;
    }
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

fn mirror(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

pub(super) fn eval(specular: Vec3, alpha: f32, wo: Vec3, wi: Vec3) -> Vec3 {
    if alpha == 0.0 || wo.z <= 0.0 || wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    let alpha = alpha.max(MIN_ALPHA);
    let h = (wo + wi).normalize();
    let g2 = 1.0 / (1.0 + lambda(alpha, wo) + lambda(alpha, wi));
    // f·cos θi = D G2 / (4 cos θo cos θi) · cos θi
    specular * (distribution(alpha, h) * g2 / (4.0 * wo.z))
}

pub(super) fn pdf(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    if alpha == 0.0 || wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let alpha = alpha.max(MIN_ALPHA);
    let h = (wo + wi).normalize();
    // Visible normals: D_wo(h) = G1(wo)·max(0, wo·h)·D(h)/cos θo, and wi = reflect(wo, h)
    // has density D_wo(h) / (4 wo·h).
    let g1 = 1.0 / (1.0 + lambda(alpha, wo));
    g1 * distribution(alpha, h) / (4.0 * wo.z)
}

pub(super) fn sample(specular: Vec3, alpha: f32, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
    if wo.z <= 0.0 {
        return None;
    }
    if alpha == 0.0 {
        return Some(BsdfSample { wi: mirror(wo), weight: specular, pdf: 1.0, delta: true });
    }
    let alpha = alpha.max(MIN_ALPHA);
    // Heitz 2018: stretch, sample the projected disk, unstretch.
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
    if wi.z <= 0.0 {
        return None;
    }
    let pdf = pdf(alpha, wo, wi);
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    // eval / pdf = specular · G2 / G1(wo)
    let weight = specular * ((1.0 + lambda(alpha, wo)) / (1.0 + lambda(alpha, wo) + lambda(alpha, wi)));
    Some(BsdfSample { wi, weight, pdf, delta: false })
}

#[cfg(test)]
mod tests {
    use super::*;
    use guiding_core::Pcg32;

    /// Sampled weights equal eval/pdf, and the pdf integrates to (at most) one over the
    /// upper hemisphere: E_uniform[pdf]·2π ≈ 1 minus the mass sampled below the horizon.
    #[test]
    fn sampling_matches_eval_and_pdf() {
        let mut rng = Pcg32::new(7, 7);
        for alpha in [0.05f32, 0.3, 0.8] {
            let wo = Vec3::new(0.4, -0.2, 0.9).normalize();
            for _ in 0..2000 {
                let Some(s) = sample(Vec3::ONE, alpha, wo, rng.next_vec2()) else { continue };
                let expected = eval(Vec3::ONE, alpha, wo, s.wi) / pdf(alpha, wo, s.wi);
                assert!((s.weight - expected).abs().max_element() < 1e-3 * expected.max_element().max(1.0));
                assert!((pdf(alpha, wo, s.wi) - s.pdf).abs() <= 1e-4 * s.pdf);
            }
            // The pdf's mass over the upper hemisphere is the share of samples that stay
            // above the horizon.
            let n = 400_000;
            let kept = (0..n).filter(|_| sample(Vec3::ONE, alpha, wo, rng.next_vec2()).is_some()).count();
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
                let total: f32 =
                    (0..n).filter_map(|_| sample(Vec3::ONE, alpha, wo, rng.next_vec2())).map(|s| s.weight.x).sum();
                let albedo = total / n as f32;
                assert!(albedo <= 1.001 && albedo > 0.3, "α = {alpha}, cos = {cos}: albedo {albedo}");
            }
        }
    }
}
