//! Area lights: every triangle whose material emits, picked in proportion to power and
//! sampled uniformly by area; optionally each cut into n² equal sub-triangles, each a
//! light of its own, so that learned selection can pick the part of a large emitter that
//! a region of the scene actually sees (a sliver through a door ajar).

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

/// Most segments an emissive triangle's edges are cut into ([`AreaLights::split`]).
pub const MAX_LIGHT_SPLIT: u32 = 16;

/// The emissive triangles of a scene, each whole or cut into sub-triangles.
#[derive(Clone, Debug, Default)]
pub struct AreaLights {
    /// Scene triangle index of each light.
    triangles: Vec<u32>,
    /// The triangle each light samples: its scene triangle, or a sub-triangle of it.
    shapes: Vec<Triangle>,
    /// Each shape's front normal (zero where it has none), kept because a light sample
    /// needs it at every vertex: normalising there cost 4–5 % of a nee path.
    normals: Vec<Vec3>,
    emission: Vec<Vec3>,
    areas: Vec<f32>,
    /// First light of each scene triangle (`u32::MAX` when it does not emit); its
    /// sub-triangles follow it.
    first_light: Vec<u32>,
    /// Segments each emissive triangle's edges are cut into (1: whole).
    split: u32,
    /// Power CDF over lights.
    cdf: Vec<f32>,
}

impl AreaLights {
    /// Collects the triangles with non-zero emission and area, each one light.
    pub fn new(triangles: &[Triangle], emission_of_triangle: impl Fn(usize) -> Vec3) -> Self {
        Self::split(triangles, emission_of_triangle, 1)
    }

    /// Collects the triangles with non-zero emission and area, each cut into `split`²
    /// equal sub-triangles (`split` segments per edge, clamped to 1..=[`MAX_LIGHT_SPLIT`]),
    /// each its own light.
    pub fn split(triangles: &[Triangle], emission_of_triangle: impl Fn(usize) -> Vec3, split: u32) -> Self {
        let split = split.clamp(1, MAX_LIGHT_SPLIT);
        let mut lights = AreaLights { first_light: vec![u32::MAX; triangles.len()], split, ..Default::default() };
        for (i, triangle) in triangles.iter().enumerate() {
            let emission = emission_of_triangle(i);
            let area = triangle.area();
            if emission.max_element() > 0.0 && area > 0.0 {
                lights.first_light[i] = lights.triangles.len() as u32;
                for sub in 0..split * split {
                    lights.triangles.push(i as u32);
                    let shape = sub_triangle(triangle, split, sub);
                    lights.normals.push(shape.normal().unwrap_or(Vec3::ZERO));
                    lights.shapes.push(shape);
                    lights.emission.push(emission);
                    lights.areas.push(area / (split * split) as f32);
                }
            }
        }
        lights.cdf = vec![0.0; lights.triangles.len()];
        let power: Vec<f32> = lights.emission.iter().zip(&lights.areas).map(|(&e, &a)| luminance(e) * a).collect();
        build_cdf(&mut lights.cdf, 0.0, |k| power[k]);
        lights
    }

    /// Number of lights (emissive triangles, or their sub-triangles).
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Segments each emissive triangle's edges are cut into (1: every light is a whole
    /// triangle).
    pub fn split_count(&self) -> u32 {
        self.split.max(1)
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

    /// The light index of a scene triangle, if it emits (its first sub-triangle's when
    /// the lights are split: see [`light_at`](Self::light_at)).
    pub fn light_of_triangle(&self, triangle: u32) -> Option<u32> {
        self.first_light.get(triangle as usize).copied().filter(|&l| l != u32::MAX)
    }

    /// The light holding the point at `barycentrics` on a scene triangle, if it emits.
    pub fn light_at(&self, triangle: u32, barycentrics: Vec2) -> Option<u32> {
        let first = self.light_of_triangle(triangle)?;
        Some(first + sub_triangle_of(self.split_count(), barycentrics))
    }

    /// A point drawn uniformly on `light`, seen from `from`; its pdf is per steradian for
    /// that light alone (multiply by the light's selection probability).
    pub fn sample_point(&self, light: u32, from: Vec3, u: Vec2) -> Option<LightSample> {
        let light = light as usize;
        let triangle = self.shapes.get(light)?;
        let point = triangle.point(square_to_triangle_barycentrics(u));
        // A shape without a normal has a zero one: no direction sees its front.
        let normal = self.normals[light];
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

    /// A point drawn uniformly on `light` from `u`, for a path that starts there: the
    /// point and the front normal it emits around (zero where the shape has none).
    pub fn emission_point(&self, light: u32, u: Vec2) -> Option<(Vec3, Vec3)> {
        let light = light as usize;
        let triangle = self.shapes.get(light)?;
        Some((triangle.point(square_to_triangle_barycentrics(u)), self.normals[light]))
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

/// Sub-triangle `index` of `triangle` cut into `split` segments per edge. In lattice
/// coordinates (i, j) = split × barycentrics, cell (i, j) with i + j < split holds an
/// upright sub-triangle and, where i + j < split − 1, an inverted one beside it (numbered
/// as [`SubTriangles`] says). Both keep the triangle's winding, so its normal.
fn sub_triangle(triangle: &Triangle, split: u32, index: u32) -> Triangle {
    let (i, j, inverted) = SubTriangles::new(split).cell(index);
    let [v0, v1, v2] = triangle.vertices;
    let n = split as f32;
    let at = |a: u32, b: u32| v0 + (v1 - v0) * (a as f32 / n) + (v2 - v0) * (b as f32 / n);
    if inverted {
        Triangle::new(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1))
    } else {
        Triangle::new(at(i, j), at(i + 1, j), at(i, j + 1))
    }
}

/// The index of the sub-triangle holding `barycentrics` (clamped onto the triangle).
fn sub_triangle_of(split: u32, barycentrics: Vec2) -> u32 {
    if split <= 1 {
        return 0;
    }
    let n = split as f32;
    let (x, y) = (barycentrics.x.clamp(0.0, 1.0) * n, barycentrics.y.clamp(0.0, 1.0) * n);
    let i = (x as u32).min(split - 1);
    let j = (y as u32).min(split - 1 - i);
    let inverted = (x - i as f32) + (y - j as f32) > 1.0 && i + j + 1 < split;
    SubTriangles::new(split).index(i, j, inverted)
}

/// The compact numbering of the split² sub-triangles: row i of the lattice holds
/// split − i upright ones and split − i − 1 inverted ones, in the order upright (i, 0),
/// inverted (i, 0), upright (i, 1), …
struct SubTriangles {
    split: u32,
}

impl SubTriangles {
    fn new(split: u32) -> Self {
        Self { split }
    }

    /// Sub-triangles before row i: Σ_{r<i} (2·(split − r) − 1).
    fn row_start(&self, i: u32) -> u32 {
        i * (2 * self.split - i)
    }

    fn index(&self, i: u32, j: u32, inverted: bool) -> u32 {
        self.row_start(i) + 2 * j + inverted as u32
    }

    fn cell(&self, index: u32) -> (u32, u32, bool) {
        let mut i = 0;
        while i + 1 < self.split && self.row_start(i + 1) <= index {
            i += 1;
        }
        let offset = index - self.row_start(i);
        (i, offset / 2, offset % 2 == 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use guiding_core::Pcg32;

    fn triangle() -> Triangle {
        Triangle::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.5, 0.0, 1.5))
    }

    #[test]
    fn sub_triangles_tile_the_triangle_and_points_find_their_own() {
        let whole = triangle();
        for split in [1, 2, 3, 6, 16] {
            let count = split * split;
            let areas: f32 = (0..count).map(|k| sub_triangle(&whole, split, k).area()).sum();
            assert!((areas - whole.area()).abs() < 1e-4 * whole.area(), "split {split}: {areas}");
            let mut rng = Pcg32::new(split as u64, 1);
            for _ in 0..2000 {
                let b = square_to_triangle_barycentrics(rng.next_vec2());
                let sub = sub_triangle_of(split, b);
                assert!(sub < count);
                // The point lies inside the sub-triangle it was given.
                let shape = sub_triangle(&whole, split, sub);
                let p = whole.point(b);
                let [a, c, d] = shape.vertices;
                let total = shape.area();
                let parts =
                    Triangle::new(p, c, d).area() + Triangle::new(a, p, d).area() + Triangle::new(a, c, p).area();
                assert!((parts - total).abs() <= 1e-3 * total, "split {split}: {b} outside sub-triangle {sub}");
            }
        }
    }

    #[test]
    fn split_lights_keep_the_power_and_sample_their_own_part() {
        let triangles = [triangle(), Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Z)];
        let emission = |i: usize| if i == 0 { Vec3::splat(2.0) } else { Vec3::ZERO };
        let whole = AreaLights::new(&triangles, emission);
        let split = AreaLights::split(&triangles, emission, 4);
        assert_eq!((whole.len(), split.len()), (1, 16));
        let power = |l: &AreaLights| l.powers().iter().sum::<f32>();
        assert!((power(&whole) - power(&split)).abs() < 1e-4 * power(&whole));
        assert_eq!(split.light_of_triangle(1), None);
        let from = Vec3::new(0.7, -1.0, 0.4); // on the side the triangle faces (−y)
        let mut rng = Pcg32::new(5, 5);
        for light in 0..16 {
            let s = split.sample_point(light, from, rng.next_vec2()).expect("the light faces the point");
            let point = from + s.wi * s.distance;
            // The hit's barycentrics on the scene triangle name the same light back.
            let [v0, v1, v2] = triangles[0].vertices;
            let (e1, e2, d) = (v1 - v0, v2 - v0, point - v0);
            let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let det = d11 * d22 - d12 * d12;
            let b = Vec2::new((d22 * d.dot(e1) - d12 * d.dot(e2)) / det, (d11 * d.dot(e2) - d12 * d.dot(e1)) / det);
            assert_eq!(split.light_at(0, b), Some(light));
            let normal = triangles[0].normal().unwrap();
            assert!((split.point_pdf(light, from, point, normal) - s.pdf).abs() <= 1e-3 * s.pdf);
        }
    }
}
