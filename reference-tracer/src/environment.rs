//! Light from infinitely far away: a sky (a constant colour or a lat-long image sampled
//! in proportion to luminance) and an optional sun, a small disk sampled on its own.
//!
//! Mapping (SCENE_FORMAT.md): direction d ↦ u = 0.5 + atan2(d.x, -d.z)/2π,
//! v = acos(d.y)/π, (0, 0) at the image's top-left, top row +y; guiding-core's
//! `environment::lat_long` implements it for both.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};
use guiding_core::cdf::{build_cdf, cdf_probability, sample_cdf};
use guiding_core::environment::lat_long::{direction_of_uv, sin_theta, texel_density, texel_of_direction};
use guiding_core::environment::SunDisk;

use crate::color::luminance;

/// An environment light: a sky and an optional sun.
#[derive(Clone, Debug)]
pub struct Environment {
    /// Radiance from every direction.
    pub sky: Sky,
    /// A small bright disk on top of the sky.
    pub sun: Option<Sun>,
    /// Probability that plain sampling picks the sun: its share of the power.
    sun_choice: f32,
}

/// The sky: radiance from every direction.
#[derive(Clone, Debug)]
pub enum Sky {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// A lat-long radiance map.
    Image(LatLongMap),
}

/// The sun: radiance from a small cone of directions, added to the sky's.
#[derive(Clone, Copy, Debug)]
pub struct Sun {
    /// Its cone of directions (and luminance, for sampling).
    pub disk: SunDisk,
    /// Radiance inside the cone.
    pub radiance: Vec3,
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

/// Texels of the luminance grid a constant sky is tiled with (its tiles then have
/// equal power per solid angle).
const CONSTANT_SKY_GRID: (usize, usize) = (64, 32);

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

    fn radiance(&self, direction: Vec3) -> Vec3 {
        let (column, row) = texel_of_direction(direction, self.width, self.height);
        self.texels[row * self.width + column]
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        let (column, row) = texel_of_direction(direction, self.width, self.height);
        let sin_theta = sin_theta(direction);
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let p_row = cdf_probability(&self.row_cdf, row);
        let p_column = cdf_probability(&self.column_cdfs[row * self.width..(row + 1) * self.width], column);
        p_row * p_column * texel_density(self.width, self.height, sin_theta)
    }

    fn sample(&self, u: Vec2) -> Vec3 {
        let (row, v_in_row) = sample_cdf(&self.row_cdf, u.x);
        let columns = &self.column_cdfs[row * self.width..(row + 1) * self.width];
        let (column, u_in_column) = sample_cdf(columns, u.y);
        direction_of_uv(Vec2::new(
            (column as f32 + u_in_column) / self.width as f32,
            (row as f32 + v_in_row) / self.height as f32,
        ))
    }

    /// Sum of luminance × texel solid angle (luminance × steradians).
    fn power(&self) -> f64 {
        let texel_solid_angle = 2.0 * std::f64::consts::PI * std::f64::consts::PI / (self.width * self.height) as f64;
        (0..self.height)
            .map(|row| {
                let sin_theta = (std::f64::consts::PI * (row as f64 + 0.5) / self.height as f64).sin();
                let line = &self.texels[row * self.width..(row + 1) * self.width];
                line.iter().map(|&t| luminance(t) as f64).sum::<f64>() * sin_theta * texel_solid_angle
            })
            .sum()
    }
}

impl Sky {
    /// Radiance arriving from direction `wi` (unit).
    pub fn radiance(&self, wi: Vec3) -> Vec3 {
        match self {
            Sky::Constant(radiance) => *radiance,
            Sky::Image(map) => map.radiance(wi),
        }
    }

    fn sample(&self, u: Vec2) -> Vec3 {
        match self {
            Sky::Constant(_) => {
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            }
            Sky::Image(map) => map.sample(u),
        }
    }

    fn pdf(&self, wi: Vec3) -> f32 {
        match self {
            Sky::Constant(_) => 0.25 / PI,
            Sky::Image(map) => map.pdf(wi),
        }
    }

    fn power(&self) -> f64 {
        match self {
            Sky::Constant(radiance) => luminance(*radiance) as f64 * 4.0 * std::f64::consts::PI,
            Sky::Image(map) => map.power(),
        }
    }

    /// The luminance of each texel, `(width, height, luminance)`, for tiling the sky
    /// (a constant sky as a uniform grid).
    pub fn luminance_grid(&self) -> (usize, usize, Vec<f32>) {
        match self {
            Sky::Constant(radiance) => {
                let (w, h) = CONSTANT_SKY_GRID;
                (w, h, vec![luminance(*radiance); w * h])
            }
            Sky::Image(map) => (map.width, map.height, map.texels.iter().map(|&t| luminance(t)).collect()),
        }
    }
}

impl Sun {
    /// Radiance arriving from `wi` (unit): the sun's inside its disk, else zero.
    pub fn radiance(&self, wi: Vec3) -> Vec3 {
        if self.disk.contains(wi) {
            self.radiance
        } else {
            Vec3::ZERO
        }
    }
}

impl Environment {
    /// A sky with an optional sun.
    pub fn new(sky: Sky, sun: Option<Sun>) -> Self {
        let sun_choice = match &sun {
            Some(sun) => {
                let (sun_power, sky_power) = (sun.disk.power() as f64, sky.power());
                if sun_power + sky_power > 0.0 {
                    (sun_power / (sun_power + sky_power)) as f32
                } else {
                    0.5
                }
            }
            None => 0.0,
        };
        Self { sky, sun, sun_choice }
    }

    /// Radiance arriving from direction `wi` (unit): sky plus sun.
    pub fn radiance(&self, wi: Vec3) -> Vec3 {
        self.sky.radiance(wi) + self.sun.as_ref().map_or(Vec3::ZERO, |sun| sun.radiance(wi))
    }

    /// Draws a direction: the sun with probability equal to its share of the power, else
    /// the sky (uniform over the sphere for a constant sky, by luminance for an image).
    pub fn sample(&self, u_choice: f32, u: Vec2) -> Option<EnvironmentSample> {
        let wi = match &self.sun {
            Some(sun) if u_choice < self.sun_choice => sun.disk.sample(u),
            _ => self.sky.sample(u),
        };
        let pdf = self.pdf(wi);
        (pdf > 0.0).then(|| EnvironmentSample { wi, radiance: self.radiance(wi), pdf })
    }

    /// Density per steradian with which [`sample`](Self::sample) produces `wi`.
    pub fn pdf(&self, wi: Vec3) -> f32 {
        let sky = (1.0 - self.sun_choice) * self.sky.pdf(wi);
        match &self.sun {
            Some(sun) if sun.disk.contains(wi) => sky + self.sun_choice * sun.disk.pdf(),
            _ => sky,
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

    /// E[L/pdf] over samples = ∫ L dω, which a fine uniform quadrature also gives.
    fn assert_samples_estimate_the_total_power(env: &Environment) {
        let mut rng = Pcg32::new(3, 1);
        let n = 400_000;
        let mut estimate = 0.0f64;
        for _ in 0..n {
            if let Some(s) = env.sample(rng.next_f32(), rng.next_vec2()) {
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
                quadrature += env.sky.radiance(d).x as f64;
            }
        }
        quadrature *= 4.0 * std::f64::consts::PI / (steps * steps) as f64;
        if let Some(sun) = &env.sun {
            quadrature += (sun.radiance.x * sun.disk.solid_angle()) as f64;
        }
        assert!((estimate - quadrature).abs() < 0.01 * quadrature, "{estimate} vs {quadrature}");
    }

    #[test]
    fn samples_match_pdf_and_estimate_the_total_power() {
        assert_samples_estimate_the_total_power(&Environment::new(Sky::Image(test_map()), None));
        let disk = SunDisk::new(Vec3::new(0.3, 0.5, -1.0), 1f32.to_radians(), 1.0e5).unwrap();
        let sun = Sun { disk, radiance: Vec3::splat(1.0e5) };
        let env = Environment::new(Sky::Image(test_map()), Some(sun));
        assert!(env.sun_choice > 0.1 && env.sun_choice < 0.9, "{}", env.sun_choice);
        assert_samples_estimate_the_total_power(&env);
        assert_samples_estimate_the_total_power(&Environment::new(Sky::Constant(Vec3::splat(0.5)), Some(sun)));
    }
}
