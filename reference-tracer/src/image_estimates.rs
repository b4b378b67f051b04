//! What the efficiency-aware roulette weighs a path against, measured on the image being
//! rendered: each pixel's expected value, the image's relative variance per sample and
//! what a path costs.

use crate::color::luminance;
use crate::film::Film;
use crate::integrator::PathCounters;
use crate::metrics::RELATIVE_EPSILON;
use crate::output::Image;

/// The image as the roulette sees it, refreshed at every refit of the guides.
#[derive(Clone, Debug, Default)]
pub struct ImageEstimates {
    /// Per pixel (row-major) the image so far, luminance, blurred over 3×3 pixels; empty
    /// before the first refit.
    pixels: Vec<f32>,
    /// Mean over pixels of a sample's variance over (pixel² + ε), as relMSE weighs it; 0
    /// before two passes of one iteration were seen.
    relative_variance: f32,
    /// Rays a camera path cast in the last pass.
    path_rays: f32,
}

impl ImageEstimates {
    /// Counts the cost of a pass's paths.
    pub fn count_pass(&mut self, counters: &PathCounters) {
        if counters.paths > 0 {
            self.path_rays = counters.rays as f32 / counters.paths as f32;
        }
    }

    /// Refreshes the pixels and the variance from `film` (its current iteration's passes
    /// counted).
    pub fn refit(&mut self, film: &Film) {
        self.pixels = blurred_luminance(&film.image());
        // Each pixel's variance over an estimate of it not made of the same samples (the
        // blurred image): a pixel whose own mean holds its one bright sample would hide
        // most of its variance (on door 160×120 the self-weighed mean was a sixth of this
        // one after 16 passes).
        if let Some(variances) = film.sample_variances() {
            let relative = variances.iter().zip(&self.pixels).map(|(v, i)| v / (i * i + RELATIVE_EPSILON));
            self.relative_variance = relative.sum::<f32>() / variances.len().max(1) as f32;
        }
    }

    /// The pixel at `index` (row-major), where known.
    pub fn pixel(&self, index: usize) -> Option<f32> {
        self.pixels.get(index).copied()
    }

    /// The image's relative variance per sample (0 while unknown).
    pub fn relative_variance(&self) -> f32 {
        self.relative_variance
    }

    /// Rays a camera path cast in the last pass (0 before one).
    pub fn path_rays(&self) -> f32 {
        self.path_rays
    }
}

/// The luminance of `image` averaged over each pixel's 3×3 neighbourhood (fewer at the
/// border): a pixel estimate less swayed by one pixel's noise.
fn blurred_luminance(image: &Image) -> Vec<f32> {
    let (width, height) = (image.width, image.height);
    let luminances: Vec<f32> = image.pixels.iter().map(|&p| luminance(p)).collect();
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let (mut sum, mut n) = (0.0, 0.0);
            for row in y.saturating_sub(1)..(y + 2).min(height) {
                for column in x.saturating_sub(1)..(x + 2).min(width) {
                    sum += luminances[row * width + column];
                    n += 1.0;
                }
            }
            sum / n
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::film::Combine;

    #[test]
    fn the_blur_keeps_a_flat_image_and_spreads_one_bright_pixel_over_its_neighbours() {
        let flat = Image { width: 4, height: 3, pixels: vec![Vec3::splat(2.0); 12] };
        assert!(blurred_luminance(&flat).iter().all(|&l| (l - 2.0).abs() < 1e-6));
        let mut pixels = vec![Vec3::ZERO; 12];
        pixels[5] = Vec3::splat(9.0);
        let blurred = blurred_luminance(&Image { width: 4, height: 3, pixels });
        assert!((blurred[5] - 1.0).abs() < 1e-6, "the centre: {}", blurred[5]);
        // The corner sees 4 pixels, one of them bright.
        assert!((blurred[0] - 9.0 / 4.0).abs() < 1e-6, "the corner: {}", blurred[0]);
        assert_eq!(blurred[3], 0.0);
    }

    #[test]
    fn the_variance_is_weighed_by_the_blurred_pixel_not_by_its_own_samples() {
        // Two passes: one pixel of four got 0 then 8, the rest 1 and 1.
        let mut film = Film::new(2, 2, Combine::Samples);
        for value in [0.0, 8.0] {
            for (i, pixel) in film.pixels_mut().iter_mut().enumerate() {
                Film::add(pixel, Vec3::splat(if i == 0 { value } else { 1.0 }));
            }
            film.end_pass();
        }
        let mut estimates = ImageEstimates::default();
        assert_eq!(estimates.relative_variance(), 0.0);
        estimates.refit(&film);
        // Every pixel's blurred estimate is (4 + 1 + 1 + 1) / 4 = 1.75; the bright one's
        // sample variance is 32, the others' 0.
        assert_eq!(estimates.pixel(3), Some(1.75));
        let expected = 32.0 / (1.75f32 * 1.75 + RELATIVE_EPSILON) / 4.0;
        assert!((estimates.relative_variance() - expected).abs() < 1e-4 * expected);
        let counters = PathCounters { paths: 4, rays: 10, ..Default::default() };
        estimates.count_pass(&counters);
        assert_eq!(estimates.path_rays(), 2.5);
    }
}
