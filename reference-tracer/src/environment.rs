//! Light from infinitely far away: a constant colour or a lat-long image sampled in
//! proportion to luminance.
//!
//! Mapping (SCENE_FORMAT.md): direction d ↦ u = 0.5 + atan2(d.x, -d.z)/2π,
//! v = acos(d.y)/π, (0, 0) at the image's top-left, top row +y.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};
use guiding_core::cdf::{build_cdf, cdf_probability, sample_cdf};

use crate::color::luminance;

/// An environment light.
#[derive(Clone, Debug)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// A lat-long radiance map.
    Image(LatLongMap),
}

/// A lat-long map with a piecewise-constant sampling distribution: rows by their
/// luminance times sin θ, then columns within the row.
#[derive(Clone, Debug)]
pub struct LatLongMap {
    width: usize,
    height: usize,
    texels: Vec<Vec3>,
    row_cdf: Vec<f32>,
    column_cdfs: Vec<f32>,
}

/// A direction drawn from the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentSample {
    /// Direction towards the environment.
    pub wi: Vec3,
    /// Radiance arriving from it.
    pub radiance: Vec3,
    /// Density per steradian.
    pub pdf: f32,
}

impl LatLongMap {
    /// A map of `width × height` texels, rows top (+y) to bottom; radiance already scaled.
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>) -> Self {
        let mut column_cdfs = vec![0.0; width * height];
        let mut row_weights = vec![0.0f32; height];
        for row in 0..height {
            let sin_theta = (PI * (row as f32 + 0.5) / height as f32).sin();
            let line = &texels[row * width..(row + 1) * width];
            build_cdf(&mut column_cdfs[row * width..(row + 1) * width], 0.0, |k| luminance(line[k]));
            row_weights[row] = line.iter().map(|&t| luminance(t)).sum::<f32>() * sin_theta;
        }
        let mut row_cdf = vec![0.0; height];
        build_cdf(&mut row_cdf, 0.0, |k| row_weights[k]);
        Self { width, height, texels, row_cdf, column_cdfs }
    }

    fn texel_of(&self, direction: Vec3) -> (usize, usize) {
        let u = 0.5 + direction.x.atan2(-direction.z) / (2.0 * PI);
        let v = direction.y.clamp(-1.0, 1.0).acos() / PI;
        let column = ((u * self.width as f32) as usize).min(self.width - 1);
        let row = ((v * self.height as f32) as usize).min(self.height - 1);
        (column, row)
    }

    fn direction_of(&self, uv: Vec2) -> Vec3 {
        let phi = 2.0 * PI * (uv.x - 0.5);
        let theta = PI * uv.y;
        Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
    }

    fn radiance(&self, direction: Vec3) -> Vec3 {
        let (column, row) = self.texel_of(direction);
        self.texels[row * self.width + column]
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        let (column, row) = self.texel_of(direction);
        let sin_theta = (1.0 - direction.y * direction.y).max(0.0).sqrt();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let p_row = cdf_probability(&self.row_cdf, row);
        let p_column = cdf_probability(&self.column_cdfs[row * self.width..(row + 1) * self.width], column);
        // Density in (u, v) is p·W·H; dω = 2π² sin θ du dv.
        p_row * p_column * (self.width * self.height) as f32 / (2.0 * PI * PI * sin_theta)
    }

    fn sample(&self, u: Vec2) -> Option<EnvironmentSample> {
        let (row, v_in_row) = sample_cdf(&self.row_cdf, u.x);
        let columns = &self.column_cdfs[row * self.width..(row + 1) * self.width];
        let (column, u_in_column) = sample_cdf(columns, u.y);
        let uv =
            Vec2::new((column as f32 + u_in_column) / self.width as f32, (row as f32 + v_in_row) / self.height as f32);
        let wi = self.direction_of(uv);
        let pdf = self.pdf(wi);
        (pdf > 0.0).then(|| EnvironmentSample { wi, radiance: self.radiance(wi), pdf })
    }
}

impl Environment {
    /// Radiance arriving from direction `wi` (unit).
    pub fn radiance(&self, wi: Vec3) -> Vec3 {
        match self {
            Environment::Constant(radiance) => *radiance,
            Environment::Image(map) => map.radiance(wi),
        }
    }

    /// Draws a direction: uniform over the sphere for a constant environment, by
    /// luminance for an image.
    pub fn sample(&self, u: Vec2) -> Option<EnvironmentSample> {
        match self {
            Environment::Constant(radiance) => {
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                Some(EnvironmentSample { wi, radiance: *radiance, pdf: 0.25 / PI })
            }
            Environment::Image(map) => map.sample(u),
        }
    }

    /// Density per steradian with which [`sample`](Self::sample) produces `wi`.
    pub fn pdf(&self, wi: Vec3) -> f32 {
        match self {
            Environment::Constant(_) => 0.25 / PI,
            Environment::Image(map) => map.pdf(wi),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use guiding_core::Pcg32;

    fn test_map() -> LatLongMap {
        let (w, h) = (16, 8);
        let texels = (0..w * h).map(|i| Vec3::splat(if i % 7 == 3 { 50.0 } else { 0.1 + (i % 5) as f32 })).collect();
        LatLongMap::new(w, h, texels)
    }

    #[test]
    fn mapping_round_trips() {
        let map = test_map();
        assert!((map.direction_of(Vec2::new(0.5, 0.0)) - Vec3::Y).length() < 1e-5);
        // u = 0.5 looks down -z.
        assert!((map.direction_of(Vec2::new(0.5, 0.5)) - Vec3::NEG_Z).length() < 1e-5);
        for (c, r) in [(0, 0), (5, 3), (15, 7), (8, 4)] {
            let uv = Vec2::new((c as f32 + 0.5) / 16.0, (r as f32 + 0.5) / 8.0);
            assert_eq!(map.texel_of(map.direction_of(uv)), (c, r));
        }
    }

    #[test]
    fn samples_match_pdf_and_estimate_the_total_power() {
        // E[L/pdf] over samples = ∫ L dω, which a fine uniform quadrature also gives.
        let env = Environment::Image(test_map());
        let mut rng = Pcg32::new(3, 1);
        let n = 200_000;
        let mut estimate = 0.0f64;
        for _ in 0..n {
            if let Some(s) = env.sample(rng.next_vec2()) {
                assert!((env.pdf(s.wi) - s.pdf).abs() <= 1e-3 * s.pdf);
                estimate += (s.radiance.x / s.pdf) as f64;
            }
        }
        estimate /= n as f64;
        let mut quadrature = 0.0f64;
        let steps = 1024;
        for i in 0..steps {
            for j in 0..steps {
                let z = -1.0 + 2.0 * (i as f32 + 0.5) / steps as f32;
                let phi = 2.0 * PI * (j as f32 + 0.5) / steps as f32;
                let r = (1.0 - z * z).sqrt();
                let d = Vec3::new(r * phi.cos(), z, r * phi.sin());
                quadrature += env.radiance(d).x as f64;
            }
        }
        quadrature *= 4.0 * std::f64::consts::PI / (steps * steps) as f64;
        assert!((estimate - quadrature).abs() < 0.01 * quadrature, "{estimate} vs {quadrature}");
    }
}
