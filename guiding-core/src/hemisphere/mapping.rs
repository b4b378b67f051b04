//! Equal-area maps from the unit square to the hemisphere, and the patch grid on them.
//!
//! A probe's hemisphere (local +z up) is the image of the unit square under an
//! area-preserving map, so a `nu × nv` grid of square cells gives `nu·nv` patches of
//! equal solid angle `2π/(nu·nv)`, and a point uniform in a cell is uniform in its patch.

use core::f32::consts::{FRAC_PI_4, PI};

use alloc::vec::Vec;
use glam::{Vec2, Vec3};

use crate::atan2::fast_atan2;
use crate::distribution::MIN_SAMPLED_COS_THETA;
use crate::error::Error;

/// Largest number of patches per hemisphere: beyond it a patch's probability can fall
/// under the 2⁻²⁴ CDF quantum even for a flat table.
pub const MAX_PATCHES: u32 = 1 << 16;

/// Which equal-area map turns the unit square into the hemisphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum HemisphereMapping {
    /// u = cos θ, v = φ/2π (Lambert's cylindrical projection): patches are bands in
    /// cos θ cut into wedges in φ; simple and exact, slivers near the pole.
    Cylindrical,
    /// Shirley–Chiu concentric square → disk, lifted to the hemisphere by the
    /// equal-area map z = 1 - r²: patches of similar shape everywhere.
    ConcentricSquare,
}

impl HemisphereMapping {
    /// The local direction (z ≥ 0, unit length) of a point of the unit square.
    pub fn square_to_hemisphere(self, uv: Vec2) -> Vec3 {
        match self {
            HemisphereMapping::Cylindrical => {
                let z = uv.x.clamp(0.0, 1.0);
                let r = libm::sqrtf((1.0 - z * z).max(0.0));
                let (sin_phi, cos_phi) = libm::sincosf(2.0 * PI * uv.y);
                Vec3::new(r * cos_phi, r * sin_phi, z)
            }
            HemisphereMapping::ConcentricSquare => {
                let disk = square_to_disk(uv);
                let r2 = disk.length_squared().min(1.0);
                let scale = libm::sqrtf(2.0 - r2);
                Vec3::new(disk.x * scale, disk.y * scale, 1.0 - r2)
            }
        }
    }

    /// The point of the unit square that maps to the local direction `local` (z ≥ 0).
    pub fn hemisphere_to_square(self, local: Vec3) -> Vec2 {
        match self {
            HemisphereMapping::Cylindrical => {
                // The patch is all a direction's square point decides (pdf and records);
                // the fast atan2 moves it only within 2e-6 rad of a patch's edge.
                let mut phi = fast_atan2(local.y, local.x);
                if phi < 0.0 {
                    phi += 2.0 * PI;
                }
                Vec2::new(local.z.clamp(0.0, 1.0), phi * (0.5 / PI))
            }
            HemisphereMapping::ConcentricSquare => {
                let r = libm::sqrtf((1.0 - local.z).max(0.0));
                let planar = libm::sqrtf(local.x * local.x + local.y * local.y);
                if planar == 0.0 {
                    return Vec2::splat(0.5);
                }
                disk_to_square(Vec2::new(local.x, local.y) * (r / planar))
            }
        }
    }
}

/// Shirley–Chiu concentric map, area-preserving from [0,1]² to the unit disk.
fn square_to_disk(uv: Vec2) -> Vec2 {
    let a = 2.0 * uv.x - 1.0;
    let b = 2.0 * uv.y - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) =
        if a.abs() > b.abs() { (a, FRAC_PI_4 * (b / a)) } else { (b, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (a / b)) };
    let (sin_phi, cos_phi) = libm::sincosf(phi);
    Vec2::new(r * cos_phi, r * sin_phi)
}

/// Inverse of [`square_to_disk`].
fn disk_to_square(p: Vec2) -> Vec2 {
    let r = p.length();
    let mut phi = libm::atan2f(p.y, p.x);
    if phi < -FRAC_PI_4 {
        phi += 2.0 * PI;
    }
    let (a, b) = if phi < FRAC_PI_4 {
        (r, phi * r / FRAC_PI_4)
    } else if phi < 3.0 * FRAC_PI_4 {
        (-(phi - 2.0 * FRAC_PI_4) * r / FRAC_PI_4, r)
    } else if phi < 5.0 * FRAC_PI_4 {
        (-r, -(phi - PI) * r / FRAC_PI_4)
    } else {
        ((phi - 6.0 * FRAC_PI_4) * r / FRAC_PI_4, -r)
    };
    Vec2::new(0.5 * (a + 1.0), 0.5 * (b + 1.0))
}

/// A hemisphere cut into `resolution[0] × resolution[1]` equal-area patches.
///
/// Patch `k` is square cell `(k / nv, k % nv)`: row `iu` along the square's u axis,
/// column `iv` along v.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PatchLayout {
    /// The square-to-hemisphere map.
    pub mapping: HemisphereMapping,
    /// Cells along u and v; their product is the patch count.
    pub resolution: [u32; 2],
}

impl Default for PatchLayout {
    /// 8 bands × 16 wedges on the cylindrical map: 128 patches of 0.049 sr.
    fn default() -> Self {
        Self { mapping: HemisphereMapping::Cylindrical, resolution: [8, 16] }
    }
}

impl PatchLayout {
    /// Checks the resolution: each axis ≥ 1, at most [`MAX_PATCHES`] patches.
    pub fn validate(&self) -> Result<(), Error> {
        let [nu, nv] = self.resolution;
        let entries = nu as u64 * nv as u64;
        if nu == 0 || nv == 0 {
            return Err(Error::InvalidSetting {
                name: "layout.resolution",
                value: entries as f64,
                requirement: "at least 1 patch along each axis",
            });
        }
        if entries > MAX_PATCHES as u64 {
            return Err(Error::ResolutionTooLarge { entries, limit: MAX_PATCHES });
        }
        Ok(())
    }

    /// Number of patches per hemisphere.
    pub fn patch_count(&self) -> usize {
        self.resolution[0] as usize * self.resolution[1] as usize
    }

    /// Solid angle of every patch, steradians: 2π / patch count.
    pub fn patch_solid_angle(&self) -> f32 {
        2.0 * PI / self.patch_count() as f32
    }

    /// The patch containing local direction `local`, or `None` below the horizon
    /// (z < 0) or for a non-finite direction.
    pub fn patch_of(&self, local: Vec3) -> Option<usize> {
        if !local.is_finite() || local.z < 0.0 {
            return None;
        }
        let uv = self.mapping.hemisphere_to_square(local);
        let [nu, nv] = self.resolution;
        let iu = ((uv.x * nu as f32) as u32).min(nu - 1);
        let iv = ((uv.y * nv as f32) as u32).min(nv - 1);
        Some((iu * nv + iv) as usize)
    }

    /// The local direction at position `xi` ∈ [0,1)² inside patch `patch`; uniform `xi`
    /// gives a direction uniform over the patch's solid angle (up to the horizon band of
    /// [`MIN_SAMPLED_COS_THETA`]).
    pub fn direction_in_patch(&self, patch: usize, xi: Vec2) -> Vec3 {
        let [nu, nv] = self.resolution;
        let iu = (patch / nv as usize) as f32;
        let iv = (patch % nv as usize) as f32;
        let uv = Vec2::new((iu + xi.x) / nu as f32, (iv + xi.y) / nv as f32);
        let d = self.mapping.square_to_hemisphere(uv);
        if d.z >= MIN_SAMPLED_COS_THETA {
            return d;
        }
        let planar = libm::sqrtf(d.x * d.x + d.y * d.y);
        let scale = libm::sqrtf(1.0 - MIN_SAMPLED_COS_THETA * MIN_SAMPLED_COS_THETA) / planar;
        Vec3::new(d.x * scale, d.y * scale, MIN_SAMPLED_COS_THETA)
    }

    /// Per patch: its centre direction (local) and `∫ cos θ dω` over it (steradians),
    /// the exact Lambertian weight. The integrals sum to π.
    pub fn patch_tables(&self) -> (Vec<Vec3>, Vec<f32>) {
        let count = self.patch_count();
        let centers: Vec<Vec3> = (0..count).map(|k| self.direction_in_patch(k, Vec2::splat(0.5))).collect();
        let mut cos_integrals: Vec<f64> = match self.mapping {
            HemisphereMapping::Cylindrical => {
                // A patch spans z ∈ [z0, z1] and Δφ = 2π/nv: ∫ z dz dφ = Δφ (z1² - z0²)/2.
                let [nu, nv] = self.resolution;
                (0..count)
                    .map(|k| {
                        let iu = (k / nv as usize) as f64;
                        let (z0, z1) = (iu / nu as f64, (iu + 1.0) / nu as f64);
                        core::f64::consts::PI / nv as f64 * (z1 * z1 - z0 * z0)
                    })
                    .collect()
            }
            HemisphereMapping::ConcentricSquare => {
                // Mean of cos θ over a uniform sub-grid of the cell, times the patch's solid
                // angle; the sub-grid keeps the whole table under ~1M evaluations.
                let steps = ((1usize << 20) / count).isqrt().clamp(2, 32);
                (0..count)
                    .map(|k| {
                        let mut sum = 0.0f64;
                        for i in 0..steps {
                            for j in 0..steps {
                                let xi = Vec2::new((i as f32 + 0.5) / steps as f32, (j as f32 + 0.5) / steps as f32);
                                sum += self.direction_in_patch(k, xi).z as f64;
                            }
                        }
                        sum / (steps * steps) as f64 * self.patch_solid_angle() as f64
                    })
                    .collect()
            }
        };
        // Remove the quadrature's residual so the weights integrate cos θ to exactly π.
        let total: f64 = cos_integrals.iter().sum();
        let correction = core::f64::consts::PI / total;
        cos_integrals.iter_mut().for_each(|c| *c *= correction);
        (centers, cos_integrals.into_iter().map(|c| c as f32).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    const MAPPINGS: [HemisphereMapping; 2] = [HemisphereMapping::Cylindrical, HemisphereMapping::ConcentricSquare];

    #[test]
    fn maps_round_trip_and_stay_on_the_hemisphere() {
        let mut rng = Pcg32::new(3, 0);
        for mapping in MAPPINGS {
            for _ in 0..20_000 {
                let uv = rng.next_vec2();
                let d = mapping.square_to_hemisphere(uv);
                assert!((d.length() - 1.0).abs() < 1e-5, "{mapping:?} {uv:?}");
                assert!(d.z >= 0.0);
                let back = mapping.hemisphere_to_square(d);
                assert!((back - uv).abs().max_element() < 2e-3, "{mapping:?} {uv:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn sampled_directions_fall_in_their_own_patch() {
        let mut rng = Pcg32::new(5, 0);
        for mapping in MAPPINGS {
            for resolution in [[1, 1], [4, 4], [8, 16], [3, 7]] {
                let layout = PatchLayout { mapping, resolution };
                for k in 0..layout.patch_count() {
                    for _ in 0..50 {
                        // Stay off the cell border, where rounding may pick the neighbour.
                        let xi = Vec2::splat(0.01) + rng.next_vec2() * 0.98;
                        let d = layout.direction_in_patch(k, xi);
                        assert_eq!(layout.patch_of(d), Some(k), "{mapping:?} {resolution:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn patches_have_equal_solid_angle() {
        // Uniform directions over the hemisphere land in every patch equally often.
        let mut rng = Pcg32::new(9, 1);
        for mapping in MAPPINGS {
            let layout = PatchLayout { mapping, resolution: [4, 4] };
            let mut counts = [0u32; 16];
            let n = 160_000;
            for _ in 0..n {
                let u = rng.next_vec2();
                let z = u.x;
                let r = libm::sqrtf(1.0 - z * z);
                let phi = 2.0 * PI * u.y;
                let d = Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z);
                counts[layout.patch_of(d).unwrap()] += 1;
            }
            for c in counts {
                let expected = n as f32 / 16.0;
                assert!((c as f32 - expected).abs() < 5.0 * expected.sqrt(), "{mapping:?} {counts:?}");
            }
        }
    }

    #[test]
    fn below_horizon_and_nan_have_no_patch() {
        let layout = PatchLayout::default();
        assert_eq!(layout.patch_of(Vec3::new(0.0, 0.0, -1.0)), None);
        assert_eq!(layout.patch_of(Vec3::NAN), None);
        assert!(layout.patch_of(Vec3::X).is_some());
    }

    #[test]
    fn cosine_integrals_sum_to_pi_and_match_between_layouts() {
        for mapping in MAPPINGS {
            let layout = PatchLayout { mapping, resolution: [8, 8] };
            let (centers, cos) = layout.patch_tables();
            assert_eq!(centers.len(), 64);
            let total: f32 = cos.iter().sum();
            assert!((total - PI).abs() < 1e-4);
            for (c, w) in centers.iter().zip(&cos) {
                // The centre's cosine times the solid angle approximates the integral.
                assert!((c.z * layout.patch_solid_angle() - w).abs() < 0.02, "{mapping:?}");
            }
        }
    }

    #[test]
    fn resolution_limits() {
        let too_big = PatchLayout { mapping: HemisphereMapping::Cylindrical, resolution: [512, 512] };
        assert!(matches!(too_big.validate(), Err(Error::ResolutionTooLarge { entries: 262_144, .. })));
        let empty = PatchLayout { mapping: HemisphereMapping::Cylindrical, resolution: [0, 4] };
        assert!(matches!(empty.validate(), Err(Error::InvalidSetting { .. })));
        assert!(PatchLayout::default().validate().is_ok());
    }
}
