//! Error of an image against a reference.

use crate::output::Image;

/// Errors averaged over pixels and channels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageError {
    /// Relative MSE: mean((I - R)² / (R² + 0.01)).
    pub relmse: f64,
    /// Mean squared error.
    pub mse: f64,
    /// Mean absolute percentage error: mean(|I - R| / (R + 0.01)).
    pub mape: f64,
}

/// Compares `image` with `reference` (same size).
pub fn image_error(image: &Image, reference: &Image) -> Option<ImageError> {
    if image.width != reference.width || image.height != reference.height {
        return None;
    }
    let mut sums = [0.0f64; 3];
    for (&i, &r) in image.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let (i, r) = (i[c] as f64, r[c] as f64);
            let d = i - r;
            sums[0] += d * d / (r * r + 0.01);
            sums[1] += d * d;
            sums[2] += d.abs() / (r.abs() + 0.01);
        }
    }
    let n = (image.pixels.len() * 3).max(1) as f64;
    Some(ImageError { relmse: sums[0] / n, mse: sums[1] / n, mape: sums[2] / n })
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
    }
}
