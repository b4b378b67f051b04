//! [`TreeDistribution`]: the sampling distribution of one region of the tree, kept to
//! the normal's hemisphere: the square's half on the normal's side where the normal lies
//! along the leaf's axis (one descent per sample or pdf), the sphere folded onto the
//! hemisphere elsewhere (two), mixed with a uniform share. In the half, optionally by
//! the tree's density times cos θ ([`super::cosine`]).

use core::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::quadtree::{self, QuadNode};
use super::square::{axis_square, from_axis_frame, square_to_direction, SQUARE_TO_SOLID_ANGLE};
use crate::distribution::{DirectionSample, DirectionalDistribution, MIN_SAMPLED_COS_THETA};
use crate::frame::Frame;

/// A normal within about 8° of a leaf's axis samples the half of the square on its side
/// (one descent per pdf); one further off folds the sphere onto its hemisphere (two).
pub(crate) const ALIGNED_COS: f32 = 0.99;

/// A half of the square holding less than this share of the mass is not sampled on its
/// own: its region samples the hemisphere uniformly.
pub(crate) const MIN_HALF_MASS: f32 = 1e-6;

/// How a region's distribution keeps to the normal's hemisphere.
#[derive(Clone, Copy, Debug, PartialEq)]
enum HemisphereMode {
    /// The normal lies along the leaf's axis: the quadtree restricted to the square's
    /// half on the normal's side (`high`: polar z ≥ 0), renormalised by `1 / mass`
    /// (by the cosine product's cell probabilities where the distribution has them).
    Half { high: bool, inverse_mass: f32 },
    /// The normal does not: the quadtree's sphere mirrored onto the hemisphere.
    Fold,
    /// The whole sphere, as the tree has it (folding switched off).
    Sphere,
    /// Only the uniform share (the half on the normal's side holds no mass).
    Uniform,
}

/// The sampling distribution of one region: the leaf's quadtree, kept to the normal's
/// hemisphere (see the settings' `fold_to_hemisphere`) and mixed with a uniform share.
#[derive(Clone, Copy, Debug)]
pub struct TreeDistribution<'a> {
    nodes: &'a [QuadNode],
    /// The cosine product's cell probabilities over `nodes`, which the half is sampled
    /// by where present.
    cosine: Option<&'a [[f32; 4]]>,
    root: u32,
    axis: u32,
    normal: Vec3,
    uniform_mix: f32,
    mode: HemisphereMode,
}

impl<'a> TreeDistribution<'a> {
    /// The distribution of the quadtree at `root` of `nodes`, built around world axis
    /// `axis`, for a surface of unit `normal`: `fold` keeps it to the normal's hemisphere,
    /// `uniform_mix` of it spread uniformly there; `cosine` (the cosine product's cell
    /// probabilities, indexed as `nodes`) samples the half of an aligned normal by it.
    pub(crate) fn new(
        nodes: &'a [QuadNode],
        cosine: Option<&'a [[f32; 4]]>,
        root: u32,
        axis: u32,
        normal: Vec3,
        uniform_mix: f32,
        fold: bool,
    ) -> Self {
        let along = normal[axis as usize];
        let cosine = cosine.filter(|c| c.len() == nodes.len());
        let mode = if !fold {
            HemisphereMode::Sphere
        } else if along.abs() >= ALIGNED_COS {
            let high = along > 0.0;
            let mass = match cosine {
                Some(cosine) => quadtree::half_mass(cosine, root, high),
                None => quadtree::half_mass(nodes, root, high),
            };
            if mass >= MIN_HALF_MASS {
                HemisphereMode::Half { high, inverse_mass: 1.0 / mass }
            } else {
                HemisphereMode::Uniform
            }
        } else {
            HemisphereMode::Fold
        };
        Self { nodes, cosine, root, axis, normal, uniform_mix, mode }
    }

    /// The density of the half's cell probabilities (the cosine product's, or the
    /// tree's own) at square point `p`, relative to uniform over the whole square.
    #[inline]
    fn half_density(&self, p: Vec2) -> f32 {
        match self.cosine {
            Some(cosine) => quadtree::square_density_by(self.nodes, cosine, self.root, p),
            None => quadtree::square_density(self.nodes, self.root, p),
        }
    }

    /// A point of the half `high` drawn by its cell probabilities, and its density.
    #[inline]
    fn sample_half(&self, u: Vec2, high: bool) -> (Vec2, f32) {
        match self.cosine {
            Some(cosine) => quadtree::sample_square_by(self.nodes, cosine, self.root, u, Some(high)),
            None => quadtree::sample_square(self.nodes, self.root, u, Some(high)),
        }
    }

    /// The quadtree's own density at `direction`, per steradian (on the whole sphere).
    #[inline]
    fn tree_pdf(&self, direction: Vec3) -> f32 {
        let p = axis_square(direction, self.axis);
        quadtree::square_density(self.nodes, self.root, p) / SQUARE_TO_SOLID_ANGLE
    }

    /// A direction from the uniform share: over the normal's hemisphere, or the sphere.
    fn sample_uniform(&self, u: Vec2) -> Vec3 {
        let sphere = self.mode == HemisphereMode::Sphere;
        let z = if sphere { 1.0 - 2.0 * u.x } else { u.x.max(MIN_SAMPLED_COS_THETA) };
        let r = libm::sqrtf((1.0 - z * z).max(0.0));
        let (s, c) = super::square::sin_cos_pi(2.0 * u.y - 1.0);
        Frame::from_normal(self.normal).to_world(Vec3::new(r * c, r * s, z))
    }

    /// The uniform share's density at `direction`, per steradian.
    #[inline]
    fn uniform_pdf(&self, direction: Vec3) -> f32 {
        if self.mode == HemisphereMode::Sphere {
            1.0 / SQUARE_TO_SOLID_ANGLE
        } else if direction.dot(self.normal) >= 0.0 {
            0.5 / PI
        } else {
            0.0
        }
    }

    /// The density of the tree's share at `direction`, per steradian, for the mode.
    #[inline]
    fn tree_share_pdf(&self, direction: Vec3) -> f32 {
        match self.mode {
            HemisphereMode::Half { high, inverse_mass } => {
                let p = axis_square(direction, self.axis);
                if (p.x >= 0.5) != high {
                    return 0.0;
                }
                self.half_density(p) * inverse_mass / SQUARE_TO_SOLID_ANGLE
            }
            HemisphereMode::Fold => {
                let c = direction.dot(self.normal);
                if c.is_nan() || c < 0.0 {
                    return 0.0;
                }
                let mirrored = direction - self.normal * (2.0 * c);
                self.tree_pdf(direction) + self.tree_pdf(mirrored)
            }
            HemisphereMode::Sphere => self.tree_pdf(direction),
            HemisphereMode::Uniform => 0.0,
        }
    }
}

impl DirectionalDistribution for TreeDistribution<'_> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let mix = if self.mode == HemisphereMode::Uniform { 1.0 } else { self.uniform_mix };
        if u.x < mix {
            let direction = self.sample_uniform(Vec2::new(u.x / mix, u.y));
            return DirectionSample { direction, pdf: self.pdf(direction) };
        }
        let u = Vec2::new(((u.x - mix) / (1.0 - mix)).min(super::square::ONE_BELOW), u.y);
        if let HemisphereMode::Half { high, inverse_mass } = self.mode {
            // The descent that draws the point gives its density: no second descent.
            let (mut p, mut density) = self.sample_half(u, high);
            // Kept off the horizon, as the other samplers keep cos θ ≥ MIN_SAMPLED_COS_THETA.
            let edge = 0.5 * MIN_SAMPLED_COS_THETA;
            if (p.x - 0.5).abs() < edge {
                p.x = if high { 0.5 + edge } else { 0.5 - edge };
                density = self.half_density(p);
            }
            let direction = from_axis_frame(square_to_direction(p), self.axis);
            let tree = density * inverse_mass / SQUARE_TO_SOLID_ANGLE;
            let pdf = mix * self.uniform_pdf(direction) + (1.0 - mix) * tree;
            return DirectionSample { direction, pdf };
        }
        let (p, density) = quadtree::sample_square(self.nodes, self.root, u, None);
        let d = from_axis_frame(square_to_direction(p), self.axis);
        let c = d.dot(self.normal);
        if self.mode == HemisphereMode::Fold && c.abs() >= MIN_SAMPLED_COS_THETA {
            // The folded pdf is the tree's density at the direction and at its mirror: the
            // descent that drew d gave one of them, one more descent gives the other.
            // Above the surface d is the direction and its mirror needs the descent; below
            // it the mirror is, and d (its mirror) has the density drawn.
            let mirror = d - self.normal * (2.0 * c);
            let folded = if c > 0.0 { d } else { mirror.normalize() };
            let descended = if c > 0.0 { mirror } else { folded };
            let tree = density / SQUARE_TO_SOLID_ANGLE + self.tree_pdf(descended);
            let pdf = mix * self.uniform_pdf(folded) + (1.0 - mix) * tree;
            return DirectionSample { direction: folded, pdf };
        }
        let direction = if self.mode == HemisphereMode::Fold && c < MIN_SAMPLED_COS_THETA {
            // Within reach of the horizon: mirrored in the tangent plane, kept just above it.
            let mirrored = d - self.normal * (c - c.abs().max(MIN_SAMPLED_COS_THETA));
            mirrored.normalize()
        } else {
            d
        };
        DirectionSample { direction, pdf: self.pdf(direction) }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        let mix = if self.mode == HemisphereMode::Uniform { 1.0 } else { self.uniform_mix };
        let tree = if mix < 1.0 { self.tree_share_pdf(direction) } else { 0.0 };
        mix * self.uniform_pdf(direction) + (1.0 - mix) * tree
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guide::Guide;
    use crate::low_discrepancy::Pcg32;
    use crate::tree::guide::tests::teach_peak_by_own_samples;
    use crate::tree::{SpatialDirectionalTree, SpatialDirectionalTreeSettings, TreeRegion};

    /// E over the sampler of 1/pdf is the solid angle of the support (2π for the
    /// folded distribution) exactly when the pdf matches the sampler everywhere: a check
    /// that reaches the deepest, spikiest cells, where a chi-square's bins cannot.
    #[test]
    fn inverse_pdf_averages_to_the_hemisphere_on_spiky_trees() {
        // Without a uniform share 1/pdf is unbounded, and the mean converges only where
        // the tree's range is moderate: the mean's fit (the root mean square's squares
        // the targets' range, and 4 M draws scatter by a few per cent).
        inverse_pdf_averages_to_the_hemisphere(0.0, false);
        inverse_pdf_averages_to_the_hemisphere(0.02, true);
    }

    fn inverse_pdf_averages_to_the_hemisphere(uniform_mix: f32, second_moment: bool) {
        let settings = SpatialDirectionalTreeSettings { uniform_mix, second_moment, ..Default::default() };
        let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
        let normal = Vec3::new(0.3, -0.5, 0.8).normalize();
        let region = tree.locate(Vec3::ZERO, normal).unwrap();
        let mut rng = Pcg32::new(3, 1);
        for _ in 0..8 {
            let snapshot = tree.clone();
            let d = snapshot.distribution(region);
            for _ in 0..50_000 {
                let s = d.sample(rng.next_vec2());
                // Heavy-tailed targets, as Russian roulette makes them.
                let u = rng.next_f32();
                let target = if u < 0.01 { 1e3 } else { 0.1 };
                tree.update_sampled(region, s.direction, target, s.pdf);
            }
            tree.rebuild_sampling();
        }
        let d = tree.distribution(region);
        let n = 2_000_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let s = d.sample(rng.next_vec2());
            sum += 1.0 / s.pdf as f64;
        }
        let mean = sum / n as f64;
        let off = (mean / (2.0 * core::f64::consts::PI) - 1.0).abs();
        assert!(off < 0.01, "E[1/pdf] = {mean} (uniform share {uniform_mix}, second moment {second_moment})");
    }

    /// Records whose normals lie along world y turn the leaf of a single spatial tree
    /// to y; the region then samples the half of the square above its surface, with the
    /// pdf the descent gave, and E[1/pdf] is still the hemisphere's 2π.
    #[test]
    fn a_leaf_turns_to_its_normals_axis_and_samples_that_half() {
        let settings = SpatialDirectionalTreeSettings { uniform_mix: 0.0, trees_per_axis: false, ..Default::default() };
        let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
        let region = tree.locate(Vec3::ZERO, Vec3::Y).unwrap();
        assert_eq!(tree.leaf_axis(region.leaf), Some(2));
        let light = Vec3::new(0.3, 0.9, -0.3).normalize();
        let mut rng = Pcg32::new(4, 2);
        teach_peak_by_own_samples(&mut tree, region, (light, 0.995, 100.0), (6, 50_000), &mut rng);
        assert_eq!(tree.leaf_axis(region.leaf), Some(1), "the square turned to the normals' axis");
        let d = tree.distribution(region);
        assert!(matches!(d.mode, HemisphereMode::Half { high: true, .. }), "{:?}", d.mode);
        let n = 1_000_000;
        let (mut sum, mut differing) = (0.0f64, 0);
        for _ in 0..n {
            let s = d.sample(rng.next_vec2());
            assert!(s.direction.y > 0.0, "{} below the surface", s.direction);
            // The pdf maps the direction back by an approximate atan2 (2e-6 rad): within
            // that of a cell's edge it may read the neighbour.
            differing += ((s.pdf / d.pdf(s.direction) - 1.0).abs() > 1e-3) as u32;
            sum += 1.0 / s.pdf as f64;
        }
        assert!(differing * 10_000 < n, "{differing} samples whose pdf differs from pdf()");
        let mean = sum / n as f64;
        assert!((mean / (2.0 * core::f64::consts::PI) - 1.0).abs() < 0.01, "E[1/pdf] = {mean}");
        assert!(d.pdf(light) > 20.0 * d.pdf(Vec3::new(-0.3, 0.9, 0.3).normalize()));
        // The other side of the same leaf samples the other half.
        let below = tree.distribution(TreeRegion { normal: -Vec3::Y, ..region });
        assert!(matches!(below.mode, HemisphereMode::Half { high: false, .. } | HemisphereMode::Uniform));
        assert!(below.sample(Vec2::new(0.3, 0.6)).direction.y < 0.0);
    }
}
