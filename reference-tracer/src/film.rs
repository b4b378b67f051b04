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
/// it gave relMSE 2.47e-4 against 2.71e-4 by inverse variance (weights then taken from
/// the whole image, without the floor below) and 3.05e-4 for the final iteration alone
/// (nee: 2.43e-4); with the focal guide, inverse variance and samples measure alike (the
/// `--combine` flag has the figures).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Combine {
    /// Only the last iteration: training iterations are discarded.
    Final,
    /// Every pass counts alike, training or not: the plain mean of all samples, unbiased
    /// whatever the guide learned.
    #[default]
    Samples,
    /// Each iteration weighted by the inverse of its mean relative variance, estimated
    /// from its own samples (an iteration of one pass, whose variance they cannot tell,
    /// borrows a neighbouring iteration's). At each pixel the weight leaves that pixel
    /// out, so it does not depend on the samples it weighs: unbiased but for what
    /// learning from a pixel's paths does to the next iteration's weights.
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

/// The least relative variance a weight divides by: an iteration whose other pixels all
/// had none (a constant image) weighs like every other such iteration.
const LEAST_VARIANCE: f64 = 1e-200;

/// A finished iteration kept for inverse-variance weighting: per pixel its mean (RGB) and
/// the pixel's own term of the iteration's relative variance.
#[derive(Clone, Debug)]
struct WeighedIteration {
    pixels: Vec<[f32; 4]>,
    /// Σ over pixels of their terms; `None` for an iteration of one pass, whose variance
    /// its own samples cannot tell (it borrows a neighbour's: see
    /// [`Film::inverse_variance_image`]).
    variance_sum: Option<f64>,
    /// Passes (samples per pixel) in it.
    passes: u32,
}

impl WeighedIteration {
    /// The relative variance of one sample at pixel `i` in this iteration, estimated from
    /// the *other* pixels: left out, the pixel's own samples do not set their weight (an
    /// iteration that missed a pixel's rare bright paths would otherwise be both darker
    /// there and heavier). `None` after one pass.
    fn sample_variance(&self, i: usize) -> Option<f64> {
        let (sum, own, pixels) = (self.variance_sum?, self.pixels[i][3] as f64, self.pixels.len());
        let others = if pixels > 1 { (sum - own).max(0.0) / (pixels - 1) as f64 } else { sum };
        Some(others * self.passes as f64)
    }
}

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
    /// Σ over finished iterations of weight × mean image (`Samples`).
    kept: Vec<[f64; 3]>,
    /// Σ of their weights.
    kept_weight: f64,
    /// The finished iterations that count (`InverseVariance`), weighed per pixel.
    weighed: Vec<WeighedIteration>,
    /// Passes in the finished iterations that count.
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
            weighed: Vec::new(),
            kept_passes: 0,
        }
    }

    /// Pixels per row.
    pub fn width(&self) -> usize {
        self.width
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

    /// The current iteration's variance of one sample's luminance, per pixel (row-major);
    /// `None` under two passes.
    pub fn sample_variances(&self) -> Option<Vec<f32>> {
        if self.passes < 2 {
            return None;
        }
        let n = self.passes as f64;
        let variances = self.sum.iter().map(|sum| {
            let mean = luminance(Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32)) as f64 / n;
            ((sum[3] - n * mean * mean) / (n - 1.0)).max(0.0) as f32
        });
        Some(variances.collect())
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
        match self.combine {
            Combine::Final => {}
            Combine::Samples if self.passes > 0 => {
                if self.kept.is_empty() {
                    self.kept = vec![[0.0; 3]; self.sum.len()];
                }
                for (kept, sum) in self.kept.iter_mut().zip(&self.sum) {
                    for c in 0..3 {
                        kept[c] += sum[c];
                    }
                }
                self.kept_weight += self.passes as f64;
                self.kept_passes += self.passes;
            }
            Combine::Samples => {}
            Combine::InverseVariance => {
                if let Some(iteration) = self.weighed_iteration() {
                    self.weighed.push(iteration);
                    self.kept_passes += self.passes;
                }
            }
        }
        self.discard_iteration();
    }

    /// The current iteration's means and relative-variance terms; `None` before its first
    /// pass, and no variance after one, where it cannot be estimated. A pixel's term is
    /// the variance of its mean luminance relative to its squared mean (+ ε).
    fn weighed_iteration(&self) -> Option<WeighedIteration> {
        if self.passes == 0 {
            return None;
        }
        let n = self.passes as f64;
        let pixels: Vec<[f32; 4]> = self
            .sum
            .iter()
            .map(|sum| {
                let mean = luminance(Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32)) as f64 / n;
                let sample_variance = ((sum[3] - n * mean * mean) / (n - 1.0)).max(0.0);
                let term = sample_variance / n / (mean * mean + RELATIVE_EPSILON);
                [(sum[0] / n) as f32, (sum[1] / n) as f32, (sum[2] / n) as f32, term as f32]
            })
            .collect();
        let variance_sum = (self.passes >= 2).then(|| pixels.iter().map(|p| p[3] as f64).sum());
        Some(WeighedIteration { pixels, variance_sum, passes: self.passes })
    }

    /// The image now: the finished iterations and the current one, each by its weight.
    pub fn image(&self) -> Image {
        let pixels = match self.combine {
            Combine::InverseVariance => self.inverse_variance_image(),
            Combine::Final | Combine::Samples => {
                let total = self.kept_weight + self.passes as f64;
                (0..self.sum.len())
                    .map(|i| {
                        let kept = self.kept.get(i).copied().unwrap_or([0.0; 3]);
                        let value = |c: usize| ((kept[c] + self.sum[i][c]) / total.max(1.0)) as f32;
                        Vec3::new(value(0), value(1), value(2))
                    })
                    .collect()
            }
        };
        Image { width: self.width, height: self.height, pixels }
    }

    /// Each pixel by Σ_k w_k m_k / Σ_k w_k over the iterations, the current one included:
    /// w_k = n_k / max(σ²_k, σ²_last), with n_k its passes and σ²_k the relative variance
    /// of one of its samples. A short iteration's σ² is mostly an underestimate where
    /// paths are heavy-tailed (the rare bright ones are missing), so no sample weighs more
    /// than one of the latest iteration, whose guide learned longest: the weights only
    /// take noisy early iterations down. An iteration of one pass, whose σ² its samples
    /// cannot tell, borrows the σ² of the nearest iteration before it that has one (a
    /// guide that learned less, so no quieter); the current iteration's first pass so
    /// counts from the start (left out, it was missing from the image until the second:
    /// at 10 s on the living room, a third of the samples). With none before it (the
    /// first pass of a render, with a guide that learned nothing) it gets no weight once
    /// another iteration has a σ², as before: weighted like its successor's samples
    /// instead, the living room's relMSE × spp at 60 s was 5.01 and 4.89 against 4.71
    /// and 4.60 (seeds 42 and 43, one run each; runs of one seed differ by about 4 %).
    fn inverse_variance_image(&self) -> Vec<Vec3> {
        let current = self.weighed_iteration();
        let iterations: Vec<&WeighedIteration> = self.weighed.iter().chain(current.as_ref()).collect();
        // For each iteration, the one whose σ² it takes: itself, else the nearest before.
        let known = |k: &usize| iterations[*k].variance_sum.is_some();
        let lender: Vec<Option<usize>> = (0..iterations.len()).map(|k| (0..=k).rev().find(known)).collect();
        (0..self.sum.len())
            .map(|i| {
                let variance = |k: usize| lender[k].and_then(|l| iterations[l].sample_variance(i));
                let latest = iterations.len().checked_sub(1).and_then(variance);
                // Each iteration's weight, or none for the render's first pass once another
                // has a σ²; before any iteration has one, every sample alike.
                let weight = |k: usize| {
                    let n = iterations[k].passes as f64;
                    match latest {
                        None => Some(n),
                        Some(latest) => variance(k).map(|v| n / v.max(latest.max(LEAST_VARIANCE))),
                    }
                };
                let (mut value, mut total) = (glam::DVec3::ZERO, 0.0f64);
                for (k, iteration) in iterations.iter().enumerate() {
                    let Some(w) = weight(k) else { continue };
                    let p = iteration.pixels[i];
                    value += w * glam::DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                    total += w;
                }
                if total > 0.0 {
                    (value / total).as_vec3()
                } else {
                    Vec3::ZERO
                }
            })
            .collect()
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
        // One pass alone shows, and is kept.
        let mut single = Film::new(1, 1, Combine::InverseVariance);
        pass(&mut single, |_| 5.0);
        assert_eq!(single.image().pixels[0].x, 5.0);
        single.end_iteration();
        assert_eq!(single.passes(), 1);
    }

    #[test]
    fn a_one_pass_iteration_borrows_the_variance_of_the_one_before() {
        // Two pixels; the first iteration one pass of 6, then two passes (1 and 3 at
        // pixel 0, 2 and 4 at pixel 1), then the current iteration's first pass of 8.
        // The current one borrows the two-pass one's σ², so at a pixel its sample weighs
        // like theirs; the first, with no iteration before it, counts for nothing once
        // the second is there: pixel 0 is (1 + 3 + 8) / 3.
        let mut film = Film::new(2, 1, Combine::InverseVariance);
        pass(&mut film, |_| 6.0);
        film.end_iteration();
        pass(&mut film, |i| 1.0 + i as f64);
        pass(&mut film, |i| 3.0 + i as f64);
        film.end_iteration();
        pass(&mut film, |_| 8.0);
        assert_eq!(film.passes(), 4);
        let image = film.image();
        assert!((image.pixels[0].x - 4.0).abs() < 1e-5, "{:?}", image.pixels[0]);
        // Before any iteration of two passes: the plain mean.
        let mut early = Film::new(2, 1, Combine::InverseVariance);
        pass(&mut early, |_| 2.0);
        early.end_iteration();
        pass(&mut early, |_| 4.0);
        assert!((early.image().pixels[0].x - 3.0).abs() < 1e-6);
    }

    #[test]
    fn inverse_variance_weights_do_not_darken_rare_bright_samples() {
        // 64 pixels, four iterations of two passes; a sample is 1000 with probability
        // 1/1000, else 1 (mean 1.999). Weighing an iteration by a variance that counts
        // the pixel's own bright sample would give that sample almost no weight, and the
        // mean would drop towards 1.
        let mut rng = guiding_core::Pcg32::new(7, 11);
        let (trials, pixels) = (2000, 64);
        let mut total = 0.0f64;
        for _ in 0..trials {
            let mut film = Film::new(pixels, 1, Combine::InverseVariance);
            for _ in 0..4 {
                for _ in 0..2 {
                    let values: Vec<f64> =
                        (0..pixels).map(|_| if rng.next_f32() < 1e-3 { 1000.0 } else { 1.0 }).collect();
                    pass(&mut film, |i| values[i]);
                }
                film.end_iteration();
            }
            total += film.image().pixels.iter().map(|p| p.x as f64).sum::<f64>();
        }
        let mean = total / (trials * pixels) as f64;
        // Standard error ≈ √(999²·0.001/8 / 128000) ≈ 0.03.
        assert!((mean - 1.999).abs() < 0.15, "mean {mean}");
    }
}
