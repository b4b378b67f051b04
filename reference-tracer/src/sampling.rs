//! Sampling routines shared by materials and lights, each beside its pdf.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// Cosine-weighted direction in the local frame (z up).
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let z = (1.0 - u.x).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// pdf of [`cosine_hemisphere`], per steradian, for local cos θ.
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) / PI
}

/// The power heuristic (β = 2) weight of a strategy with density `pdf` against `other`.
pub fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    if a + b > 0.0 && a.is_finite() {
        a / (a + b)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_samples_match_their_pdf() {
        // E[1/pdf] over the sampled hemisphere is its solid angle restricted to pdf > 0: 2π.
        let mut rng = guiding_core::Pcg32::new(1, 1);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let d = cosine_hemisphere(rng.next_vec2());
            assert!((d.length() - 1.0).abs() < 1e-5 && d.z >= 0.0);
            if d.z > 1e-4 {
                sum += 1.0 / cosine_hemisphere_pdf(d.z) as f64;
            }
        }
        assert!((sum / n as f64 - 2.0 * std::f64::consts::PI).abs() < 0.05);
    }

    #[test]
    fn power_heuristic_edges() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-7);
    }
}
