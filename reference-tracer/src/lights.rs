//! Area lights: every triangle whose material emits, picked in proportion to power and
//! sampled uniformly by area.

use glam::{Vec2, Vec3};
use guiding_core::cdf::{build_cdf, cdf_probability, sample_cdf};
use guiding_core::{square_to_triangle_barycentrics, Triangle};

use crate::color::luminance;

/// A point drawn on a light, seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point to the light point.
    pub wi: Vec3,
    /// Distance to the light point.
    pub distance: f32,
    /// Emitted radiance towards the shading point (zero from the back face).
    pub radiance: Vec3,
    /// Density of `wi` per steradian (for the light it was drawn on).
    pub pdf: f32,
}

/// The emissive triangles of a scene.
#[derive(Clone, Debug, Default)]
pub struct AreaLights {
    /// Scene triangle index of each light.
    triangles: Vec<u32>,
    emission: Vec<Vec3>,
    areas: Vec<f32>,
    /// Light index of each scene triangle (`u32::MAX` when it does not emit).
    light_of_triangle: Vec<u32>,
    /// Power CDF over lights.
    cdf: Vec<f32>,
}

impl AreaLights {
    /// Collects the triangles with non-zero emission and area.
    pub fn new(triangles: &[Triangle], emission_of_triangle: impl Fn(usize) -> Vec3) -> Self {
        let mut lights = AreaLights { light_of_triangle: vec![u32::MAX; triangles.len()], ..Default::default() };
        for (i, triangle) in triangles.iter().enumerate() {
            let emission = emission_of_triangle(i);
            let area = triangle.area();
            if emission.max_element() > 0.0 && area > 0.0 {
                lights.light_of_triangle[i] = lights.triangles.len() as u32;
                lights.triangles.push(i as u32);
                lights.emission.push(emission);
                lights.areas.push(area);
            }
        }
        lights.cdf = vec![0.0; lights.triangles.len()];
        let power: Vec<f32> = lights.emission.iter().zip(&lights.areas).map(|(&e, &a)| luminance(e) * a).collect();
        build_cdf(&mut lights.cdf, 0.0, |k| power[k]);
        lights
    }

    /// Number of emissive triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the scene has no area lights.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Power of each light (luminance × area), in light order.
    pub fn powers(&self) -> Vec<f32> {
        self.emission.iter().zip(&self.areas).map(|(&e, &a)| luminance(e) * a).collect()
    }

    /// Picks a light in proportion to power: its index and probability.
    pub fn select_by_power(&self, u: f32) -> (u32, f32) {
        let (light, _) = sample_cdf(&self.cdf, u);
        (light as u32, cdf_probability(&self.cdf, light))
    }

    /// The probability [`select_by_power`](Self::select_by_power) gives `light`.
    pub fn power_probability(&self, light: u32) -> f32 {
        cdf_probability(&self.cdf, light as usize)
    }

    /// The scene triangle of `light`, its emitted radiance and its area.
    pub fn light(&self, light: u32) -> (u32, Vec3, f32) {
        let l = light as usize;
        (self.triangles[l], self.emission[l], self.areas[l])
    }

    /// The power CDF lights are selected by (guiding-core's [`cdf`](guiding_core::cdf)
    /// layout).
    pub fn power_cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// The light index of a scene triangle, if it emits.
    pub fn light_of_triangle(&self, triangle: u32) -> Option<u32> {
        self.light_of_triangle.get(triangle as usize).copied().filter(|&l| l != u32::MAX)
    }

    /// A point drawn uniformly on `light`, seen from `from`; its pdf is per steradian for
    /// that light alone (multiply by the light's selection probability).
    pub fn sample_point(&self, light: u32, triangles: &[Triangle], from: Vec3, u: Vec2) -> Option<LightSample> {
        let light = light as usize;
        let triangle = &triangles[*self.triangles.get(light)? as usize];
        let point = triangle.point(square_to_triangle_barycentrics(u));
        let normal = triangle.normal()?;
        let to_light = point - from;
        let distance2 = to_light.length_squared();
        let distance = distance2.sqrt();
        if !(distance.is_finite() && distance > 0.0) {
            return None;
        }
        let wi = to_light / distance;
        let cos_light = -normal.dot(wi);
        if cos_light <= 0.0 {
            return None;
        }
        let pdf = distance2 / (cos_light * self.areas[light]);
        Some(LightSample { wi, distance, radiance: self.emission[light], pdf })
    }

    /// Density per steradian with which [`sample_point`](Self::sample_point) produces the
    /// direction from `from` to `point` on `light` (normal `normal`).
    pub fn point_pdf(&self, light: u32, from: Vec3, point: Vec3, normal: Vec3) -> f32 {
        let to_light = point - from;
        let distance2 = to_light.length_squared();
        let cos_light = -normal.dot(to_light) / distance2.sqrt();
        if cos_light <= 0.0 {
            return 0.0;
        }
        distance2 / (cos_light * self.areas[light as usize])
    }
}
