//! Error of an image against a reference.

use crate::output::Image;

/// The ε of relative errors: a pixel's squared error counts over (R² + ε), so black
/// pixels do not divide by zero.
pub const RELATIVE_EPSILON: f32 = 0.01;

/// Errors averaged over pixels and channels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageError {
    /// Relative MSE: mean((I - R)² / (R² + 0.01)).
    pub relmse: f64,
    /// Mean squared error.
    pub mse: f64,
    /// Mean absolute percentage error: mean(|I - R| / (R + 0.01)).
    pub mape: f64,
    /// The median pixel's relative squared error (its channels' mean): what a typical
    /// pixel sees, untouched by a few fireflies.
    pub median_relmse: f64,
    /// The share of the relMSE held by the worst 1 % of pixels: near 0.01 for even
    /// noise, near 1 where a few fireflies make the error.
    pub worst_share: f64,
}

/// Compares `image` with `reference` (same size).
pub fn image_error(image: &Image, reference: &Image) -> Option<ImageError> {
    if image.width != reference.width || image.height != reference.height {
        return None;
    }
    let mut sums = [0.0f64; 3];
    let mut per_pixel = Vec::with_capacity(image.pixels.len());
    for (&i, &r) in image.pixels.iter().zip(&reference.pixels) {
        let mut pixel = 0.0;
        for c in 0..3 {
            let (i, r) = (i[c] as f64, r[c] as f64);
            let d = i - r;
            pixel += d * d / (r * r + RELATIVE_EPSILON as f64);
            sums[1] += d * d;
            sums[2] += d.abs() / (r.abs() + 0.01);
        }
        sums[0] += pixel;
        per_pixel.push(pixel / 3.0);
    }
    let n = (image.pixels.len() * 3).max(1) as f64;
    per_pixel.sort_by(|a, b| b.total_cmp(a));
    let median_relmse = per_pixel.get(per_pixel.len() / 2).copied().unwrap_or(0.0);
    let worst: f64 = per_pixel[..per_pixel.len().div_ceil(100)].iter().sum();
    let total: f64 = per_pixel.iter().sum();
    let worst_share = if total > 0.0 { worst / total } else { 0.0 };
    Some(ImageError { relmse: sums[0] / n, mse: sums[1] / n, mape: sums[2] / n, median_relmse, worst_share })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn errors_of_known_images() {
        let reference = Image { width: 2, height: 1, pixels: vec![Vec3::splat(1.0), Vec3::ZERO] };
        let same = image_error(&reference, &reference).unwrap();
        assert_eq!(same, ImageError::default());
        let brighter = Image { width: 2, height: 1, pixels: vec![Vec3::splat(2.0), Vec3::splat(0.1)] };
        let e = image_error(&brighter, &reference).unwrap();
        assert!((e.mse - (1.0 + 0.01) / 2.0).abs() < 1e-6);
        assert!((e.relmse - (1.0 / 1.01 + 0.01 / 0.01) / 2.0).abs() < 1e-6);
        assert!((e.mape - (1.0 / 1.01 + 0.1 / 0.01) / 2.0).abs() < 1e-5);
        assert!(image_error(&brighter, &Image { width: 1, height: 1, pixels: vec![Vec3::ZERO] }).is_none());
        // One firefly among 200 even pixels: the median sees the even ones, the worst 1 %
        // (two pixels) hold nearly all the error.
        let flat = Image { width: 200, height: 1, pixels: vec![Vec3::splat(1.0); 200] };
        let mut noisy = Image { width: 200, height: 1, pixels: vec![Vec3::splat(1.1); 200] };
        noisy.pixels[7] = Vec3::splat(101.0);
        let e = image_error(&noisy, &flat).unwrap();
        assert!((e.median_relmse - 0.01 / 1.01).abs() < 1e-6, "{e:?}");
        assert!(e.worst_share > 0.99, "{e:?}");
    }
}
