//! The image a progressive render accumulates, and how the iterations of the iterative
//! schedule combine into it: the frozen last one alone (Müller et al. 2017), every
//! sample alike, or each iteration weighted by the inverse of its estimated variance
//! (Müller 2019, "Practical Path Guiding in Production", §5).

use glam::Vec3;

use crate::color::luminance;
use crate::output::Image;

/// How the iterations of a render (training iterations and the final one) combine.
///
/// `Samples` by default: on cornell (128², guided-nee, tree, first vertex guided, 20 s)
/// it gave relMSE 2.47e-4 against 2.71e-4 by inverse variance and 3.05e-4 for the final
/// iteration alone (nee: 2.43e-4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Combine {
    /// Only the last iteration: training iterations are discarded.
    Final,
    /// Every pass counts alike, training or not: the plain mean of all samples, unbiased
    /// whatever the guide learned.
    #[default]
    Samples,
    /// Each iteration weighted by the inverse of its mean relative variance, estimated
    /// from its own samples (iterations of one pass get no weight: their variance cannot
    /// be estimated). Consistent; the weights, estimated from the same samples, leave a
    /// small bias.
    InverseVariance,
}

impl Combine {
    /// Every combination, in the order the command line lists them.
    pub const ALL: [Combine; 3] = [Combine::Final, Combine::Samples, Combine::InverseVariance];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Combine::Final => "final",
            Combine::Samples => "samples",
            Combine::InverseVariance => "inverse-variance",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == name)
            .ok_or_else(|| format!("unknown combination `{name}` (final, samples, inverse-variance)"))
    }
}

/// ε of the relative variance, as in relMSE: keeps dark pixels from dominating.
const RELATIVE_EPSILON: f64 = 1e-2;

/// Per-pixel sums of the current iteration, and the weighted images of the finished ones.
#[derive(Clone, Debug)]
pub struct Film {
    width: usize,
    height: usize,
    combine: Combine,
    /// Σ of the current iteration's samples per pixel: RGB, then squared luminance.
    sum: Vec<[f64; 4]>,
    /// Passes in the current iteration.
    passes: u32,
    /// Σ over finished iterations of weight × mean image.
    kept: Vec<[f64; 3]>,
    /// Σ of their weights.
    kept_weight: f64,
    /// Passes in them.
    kept_passes: u32,
}

impl Film {
    /// An empty film of `width` × `height` pixels.
    pub fn new(width: usize, height: usize, combine: Combine) -> Self {
        Self {
            width,
            height,
            combine,
            sum: vec![[0.0; 4]; width * height],
            passes: 0,
            kept: Vec::new(),
            kept_weight: 0.0,
            kept_passes: 0,
        }
    }

    /// Passes in the image: the finished iterations that count and the current one.
    pub fn passes(&self) -> u32 {
        self.kept_passes + self.passes
    }

    /// The current iteration's per-pixel sums, row by row, for a pass to
    /// [`add`](Self::add) its samples to.
    pub fn pixels_mut(&mut self) -> &mut [[f64; 4]] {
        &mut self.sum
    }

    /// Adds one sample of `radiance` to a pixel of [`pixels_mut`](Self::pixels_mut).
    #[inline]
    pub fn add(pixel: &mut [f64; 4], radiance: Vec3) {
        let l = luminance(radiance) as f64;
        for c in 0..3 {
            pixel[c] += radiance[c] as f64;
        }
        pixel[3] += l * l;
    }

    /// Counts a pass whose samples have been added.
    pub fn end_pass(&mut self) {
        self.passes += 1;
    }

    /// Takes the current iteration's passes out again (training the image never uses).
    pub fn discard_iteration(&mut self) {
        self.sum.iter_mut().for_each(|p| *p = [0.0; 4]);
        self.passes = 0;
    }

    /// Ends the current iteration: it joins the image with its weight (or, combining
    /// `Final`, is discarded).
    pub fn end_iteration(&mut self) {
        let weight = self.iteration_weight();
        if weight > 0.0 {
            if self.kept.is_empty() {
                self.kept = vec![[0.0; 3]; self.sum.len()];
            }
            let scale = weight / self.passes as f64;
            for (kept, sum) in self.kept.iter_mut().zip(&self.sum) {
                for c in 0..3 {
                    kept[c] += scale * sum[c];
                }
            }
            self.kept_weight += weight;
            self.kept_passes += self.passes;
        }
        self.discard_iteration();
    }

    /// The weight of the current iteration's mean image in the combination; 0 for one
    /// that does not count.
    fn iteration_weight(&self) -> f64 {
        if self.passes == 0 {
            return 0.0;
        }
        match self.combine {
            Combine::Final => 0.0,
            Combine::Samples => self.passes as f64,
            Combine::InverseVariance => {
                let variance = self.relative_variance();
                if variance.is_finite() && variance > 0.0 {
                    1.0 / variance
                } else {
                    0.0
                }
            }
        }
    }

    /// The current iteration's mean over pixels of the variance of each pixel's mean
    /// luminance, relative to its squared mean (+ ε); NaN under two passes.
    fn relative_variance(&self) -> f64 {
        let n = self.passes as f64;
        if self.passes < 2 {
            return f64::NAN;
        }
        let total: f64 = self
            .sum
            .iter()
            .map(|sum| {
                let mean = luminance(Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32)) as f64 / n;
                let sample_variance = ((sum[3] - n * mean * mean) / (n - 1.0)).max(0.0);
                sample_variance / n / (mean * mean + RELATIVE_EPSILON)
            })
            .sum();
        total / self.sum.len().max(1) as f64
    }

    /// The image now: the finished iterations and the current one, each by its weight.
    /// While the current one has no weight of its own yet (combining by inverse variance
    /// after one pass), it is left out unless nothing else is there.
    pub fn image(&self) -> Image {
        let current = self.iteration_weight();
        let (current, total) = match (current > 0.0, self.kept_weight > 0.0) {
            (true, _) => (current, self.kept_weight + current),
            (false, true) => (0.0, self.kept_weight),
            (false, false) => (1.0, 1.0),
        };
        let scale = if self.passes > 0 { current / self.passes as f64 } else { 0.0 };
        let pixels = (0..self.sum.len())
            .map(|i| {
                let kept = self.kept.get(i).copied().unwrap_or([0.0; 3]);
                let value = |c: usize| ((kept[c] + scale * self.sum[i][c]) / total) as f32;
                Vec3::new(value(0), value(1), value(2))
            })
            .collect();
        Image { width: self.width, height: self.height, pixels }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Adds a pass of grey `value` at every pixel.
    fn pass(film: &mut Film, value: impl Fn(usize) -> f64) {
        for (i, pixel) in film.pixels_mut().iter_mut().enumerate() {
            Film::add(pixel, Vec3::splat(value(i) as f32));
        }
        film.end_pass();
    }

    #[test]
    fn samples_weigh_every_pass_alike_and_final_keeps_the_last_iteration() {
        for (combine, expected) in [(Combine::Samples, 2.25), (Combine::Final, 3.0)] {
            let mut film = Film::new(2, 1, combine);
            pass(&mut film, |_| 1.0);
            film.end_iteration();
            pass(&mut film, |_| 2.0);
            pass(&mut film, |_| 3.0);
            film.end_iteration();
            pass(&mut film, |_| 3.0);
            let image = film.image();
            assert!((image.pixels[0].x as f64 - expected).abs() < 1e-6, "{combine:?}: {:?}", image.pixels[0]);
            assert_eq!(film.passes(), if combine == Combine::Final { 1 } else { 4 });
        }
    }

    #[test]
    fn inverse_variance_favours_the_quieter_iteration() {
        let mut film = Film::new(2, 1, Combine::InverseVariance);
        // A noisy iteration (0 and 4 around 2) and a quiet one (1.9 and 2.1 around 2.0).
        for v in [0.0, 4.0, 0.0, 4.0] {
            pass(&mut film, |_| v + 1.0);
        }
        film.end_iteration();
        for v in [1.9, 2.1, 1.9, 2.1] {
            pass(&mut film, |_| v + 0.0);
        }
        let value = film.image().pixels[0].x as f64;
        // The noisy iteration's mean is 3, the quiet one's 2: the image stays near 2.
        assert!(value > 2.0 && value < 2.05, "{value}");
        // One pass alone shows, but counts for nothing once another iteration is there.
        let mut single = Film::new(1, 1, Combine::InverseVariance);
        pass(&mut single, |_| 5.0);
        assert_eq!(single.image().pixels[0].x, 5.0);
        single.end_iteration();
        assert_eq!(single.passes(), 0);
    }
}
