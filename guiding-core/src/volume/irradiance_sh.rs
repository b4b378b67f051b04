//! Order-2 spherical harmonics of a Q table and the cosine-weighted integral they give
//! for any normal (Ramamoorthi & Hanrahan, "An efficient representation for irradiance
//! environment maps", 2001): nine numbers per leaf instead of a sum over its patches.

use alloc::vec::Vec;

use glam::{Vec2, Vec3};

use super::sphere_layout::SphereLayout;

/// The normalisation constants of the real SH basis of order ≤ 2, in the order
/// the basis below uses them: Y₀₀; the three l = 1; xy, yz and xz; 3z² − 1; x² − y². A GPU
/// tracer evaluating the same basis takes them from here.
pub const SH_NORMALIZATION: [f32; 5] = [0.282_095, 0.488_603, 1.092_548, 0.315_392, 0.546_274];

/// The nine real SH basis functions Y_lm (l ≤ 2) at unit direction `d`.
#[inline]
fn basis(d: Vec3) -> [f32; 9] {
    let [k0, k1, k2, k3, k4] = SH_NORMALIZATION;
    [
        k0,
        k1 * d.y,
        k1 * d.z,
        k1 * d.x,
        k2 * d.x * d.y,
        k2 * d.y * d.z,
        k3 * (3.0 * d.z * d.z - 1.0),
        k2 * d.x * d.z,
        k4 * (d.x * d.x - d.y * d.y),
    ]
}

/// ∫ Y_lm dω over every patch of `layout`, by 3×3-point Gauss–Legendre in (z, φ): exact
/// for the z-polynomial parts, so a large constant Q leaks nothing into the l = 2 bands.
pub(crate) fn patch_basis_integrals(layout: &SphereLayout) -> Vec<[f32; 9]> {
    const NODES: [f64; 3] = [-0.774_596_669_241_483_4, 0.0, 0.774_596_669_241_483_4];
    const WEIGHTS: [f64; 3] = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    (0..layout.patch_count())
        .map(|k| {
            let mut sum = [0.0f64; 9];
            for (a, wa) in NODES.iter().zip(WEIGHTS) {
                for (b, wb) in NODES.iter().zip(WEIGHTS) {
                    let u = Vec2::new((0.5 + 0.5 * a) as f32, (0.5 + 0.5 * b) as f32);
                    let y = basis(layout.direction_in_patch(k, u));
                    for (s, y) in sum.iter_mut().zip(y) {
                        *s += 0.25 * wa * wb * y as f64;
                    }
                }
            }
            sum.map(|s| (s * layout.patch_solid_angle() as f64) as f32)
        })
        .collect()
}

/// Projects a table onto the basis: L_lm = Σ_j q_j·∫_{patch j} Y_lm dω.
pub(crate) fn project(q: impl Iterator<Item = f32>, basis_integrals: &[[f32; 9]]) -> [f32; 9] {
    let mut sh = [0.0f64; 9];
    for (value, integrals) in q.zip(basis_integrals) {
        for (coefficient, &y) in sh.iter_mut().zip(integrals) {
            *coefficient += value as f64 * y as f64;
        }
    }
    sh.map(|c| c.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32)
}

/// ∫ Q(ω)·max(0, n·ω)/π dω for unit `normal` from the projection: Σ Â_l L_lm Y_lm(n)/π
/// with Â = (π, 2π/3, π/4), clamped at 0 (truncation can ring below it where Q is dark).
#[inline]
pub(crate) fn cosine_integral(sh: &[f32; 9], normal: Vec3) -> f32 {
    const BAND_WEIGHTS: [f32; 9] = [1.0, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0, 0.25, 0.25, 0.25, 0.25, 0.25];
    let y = basis(normal);
    // BAND_WEIGHTS = Â_l/π: the integrand's 1/π cancels Â's π.
    let sum: f32 = (0..9).map(|i| BAND_WEIGHTS[i] * sh[i] * y[i]).sum();
    sum.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    #[test]
    fn smooth_tables_give_the_cosine_integral_and_steps_stay_exact() {
        let fine = SphereLayout { resolution: [64, 128] };
        let centers: Vec<Vec3> =
            (0..fine.patch_count()).map(|k| fine.direction_in_patch(k, Vec2::splat(0.5))).collect();
        let brute = |q: &dyn Fn(Vec3) -> f32, n: Vec3| -> f32 {
            centers.iter().map(|&c| q(c) * c.dot(n).max(0.0) / PI * fine.patch_solid_angle()).sum()
        };
        let smooth = |d: Vec3| 1.0 + 0.5 * d.x + 0.3 * d.z * d.z;
        let step = |d: Vec3| if d.z > 0.0 { 1.0 } else { 100.0 };
        // The volume's own coarse layout: the projection must not depend on its coarseness
        // for tables that are constant per band.
        let coarse = SphereLayout { resolution: [16, 16] };
        let integrals = patch_basis_integrals(&coarse);
        let coarse_centers: Vec<Vec3> =
            (0..coarse.patch_count()).map(|k| coarse.direction_in_patch(k, Vec2::splat(0.5))).collect();
        for (q, tolerance) in [(&smooth as &dyn Fn(Vec3) -> f32, 0.02), (&step, 0.01)] {
            let sh = project(coarse_centers.iter().map(|&c| q(c)), &integrals);
            for n in [Vec3::Z, Vec3::X, Vec3::new(0.3, -0.5, 0.81).normalize()] {
                let (expected, got) = (brute(q, n), cosine_integral(&sh, n));
                assert!((got - expected).abs() < tolerance * expected.max(1.0), "n = {n}: {got} vs {expected}");
            }
        }
    }
}
