//! Shared pieces of the workspace tests: small scenes and the entry access the generic
//! guide harness needs.
#![allow(dead_code)]

use glam::{Vec2, Vec3};
use guiding_core::mixture::{VmfLobe, VmfMixture};
use guiding_core::{
    DirectionSample, DirectionalDistribution, Frame, GaussianMixture, GaussianMixtureSettings, Guide, HemisphereGrid,
    HemisphereGridSettings, HemisphereMapping, IrradianceVolume, IrradianceVolumeSettings, MixtureRegion, PatchLayout,
    ProbeId, SpatialDirectionalTree, SpatialDirectionalTreeSettings, TreeRegion, Triangle, UpdateRule, VolumeRegion,
};

/// Which way a box's faces look.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Winding {
    /// Front faces point into the box (a room).
    Inward,
    /// Front faces point out of the box (a solid).
    Outward,
}

/// The 12 triangles of the axis-aligned box `min`–`max`.
pub fn box_triangles(min: Vec3, max: Vec3, winding: Winding) -> Vec<Triangle> {
    let corner = |i: u32| Vec3::select(glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), max, min);
    // Quads wound counter-clockwise seen from outside.
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3]];
    quads
        .iter()
        .flat_map(|q| {
            let [a, b, c, d] = q.map(corner);
            match winding {
                Winding::Outward => [Triangle::new(a, b, c), Triangle::new(a, c, d)],
                Winding::Inward => [Triangle::new(a, c, b), Triangle::new(a, d, c)],
            }
        })
        .collect()
}

/// The six inward-facing walls of the box [-1, 1]³.
pub fn box_walls() -> Vec<Triangle> {
    box_triangles(Vec3::NEG_ONE, Vec3::ONE, Winding::Inward)
}

/// What the generic harness needs from a guide beyond the [`Guide`] trait: regions to
/// test and direct access to their entries (a table's patches, a mixture's lobes).
pub trait GuideAccess: Guide {
    /// A few surface points (position, normal) spread over the scene.
    fn test_points(&self) -> Vec<(Vec3, Vec3)>;
    /// The regions of [`test_points`](Self::test_points), with their normals.
    fn test_regions(&self) -> Vec<(Self::Region, Vec3)> {
        self.test_points()
            .into_iter()
            .map(|(p, n)| (self.locate(p, n).expect("the test points carry regions"), n))
            .collect()
    }
    /// The guide over [`box_walls`] sized by a byte budget alone (every other setting
    /// its default), for the memory checks.
    fn with_budget(budget_bytes: usize) -> Self;
    /// Entries per region.
    fn entry_count(&self) -> usize;
    /// Overwrites a region's entries (one non-negative value per entry: Q of a patch,
    /// the mass ∫Q dω a lobe carries).
    fn set_entries(&mut self, region: Self::Region, values: &[f32]);
    /// Every entry of every region.
    fn all_values(&self) -> Vec<f32>;
    /// The floor no entry may go under.
    fn floor(&self) -> f32;
    /// Levels of adaptive refinement [`pdf_integral`](guiding_core::validation::pdf_integral)
    /// needs: tables are piecewise constant and refine only along patch borders; a smooth
    /// pdf refines everywhere, and 3 levels already resolve a 5° lobe.
    fn integration_depth(&self) -> u32 {
        6
    }
}

/// Guides whose entries are Q values updated one target at a time (Eq. 1 per entry).
pub trait TableAccess: GuideAccess {
    /// Q of the entry that holds `direction`.
    fn entry_value(&self, region: Self::Region, direction: Vec3) -> f32;
}

/// The three inward normals of [`GuideAccess::test_points`] over [`box_walls`]: the
/// floor, a wall and the ceiling.
pub fn box_test_points() -> Vec<(Vec3, Vec3)> {
    vec![
        (Vec3::new(0.1, -1.0, 0.2), Vec3::Y),
        (Vec3::new(-1.0, 0.3, -0.4), Vec3::X),
        (Vec3::new(0.5, 1.0, 0.5), -Vec3::Y),
    ]
}

/// A 96-probe hemisphere grid over [`box_walls`] with the given mapping and rule.
pub fn hemisphere_grid(mapping: HemisphereMapping, rule: UpdateRule) -> HemisphereGrid {
    let settings = HemisphereGridSettings {
        probe_count: Some(96),
        layout: PatchLayout { mapping, ..Default::default() },
        update_rule: rule,
        ..Default::default()
    };
    HemisphereGrid::build(&box_walls(), settings).expect("grid over the box")
}

impl GuideAccess for HemisphereGrid {
    fn test_points(&self) -> Vec<(Vec3, Vec3)> {
        box_test_points()
    }

    fn with_budget(budget_bytes: usize) -> Self {
        HemisphereGrid::build(&box_walls(), HemisphereGridSettings { budget_bytes, ..Default::default() })
            .expect("grid over the box")
    }

    fn entry_count(&self) -> usize {
        self.patch_count()
    }

    fn set_entries(&mut self, region: ProbeId, values: &[f32]) {
        self.set_q_values(region, values);
    }

    fn all_values(&self) -> Vec<f32> {
        self.q_values().iter().map(|q| f32::from_bits(q.load(std::sync::atomic::Ordering::Relaxed))).collect()
    }

    fn floor(&self) -> f32 {
        self.settings().q_floor
    }
}

impl TableAccess for HemisphereGrid {
    fn entry_value(&self, region: ProbeId, direction: Vec3) -> f32 {
        let local = Frame::from_normal(self.probe_normals()[region.0 as usize]).to_local(direction);
        let patch = self.settings().layout.patch_of(local).expect("direction in the probe's hemisphere");
        self.q(region, patch)
    }
}

/// An irradiance volume over [`box_walls`]' box: a 3×3×3 grid of 16×16-patch leaves
/// with room to split.
pub fn irradiance_volume(rule: UpdateRule) -> IrradianceVolume {
    let settings = IrradianceVolumeSettings {
        budget_bytes: 400 << 10,
        resolution: Some([3, 3, 3]),
        update_rule: rule,
        ..Default::default()
    };
    IrradianceVolume::new(Vec3::NEG_ONE, Vec3::ONE, settings).expect("volume over the box")
}

impl GuideAccess for IrradianceVolume {
    fn test_points(&self) -> Vec<(Vec3, Vec3)> {
        box_test_points()
    }

    fn with_budget(budget_bytes: usize) -> Self {
        let settings = IrradianceVolumeSettings { budget_bytes, ..Default::default() };
        IrradianceVolume::new(Vec3::NEG_ONE, Vec3::ONE, settings).expect("volume over the box")
    }

    fn entry_count(&self) -> usize {
        self.patch_count()
    }

    fn set_entries(&mut self, region: VolumeRegion, values: &[f32]) {
        self.set_q_values(region.leaf, values);
    }

    fn all_values(&self) -> Vec<f32> {
        self.q_values().iter().map(|q| f32::from_bits(q.load(std::sync::atomic::Ordering::Relaxed))).collect()
    }

    fn floor(&self) -> f32 {
        self.settings().q_floor
    }
}

impl TableAccess for IrradianceVolume {
    fn entry_value(&self, region: VolumeRegion, direction: Vec3) -> f32 {
        let patch = self.settings().layout.patch_of(direction).expect("a unit direction");
        self.q(region.leaf, patch)
    }
}

/// A mixture guide over [`box_walls`]' box, 3×3×3 cells, with the given rule.
pub fn gaussian_mixture(rule: UpdateRule) -> GaussianMixture {
    let settings = GaussianMixtureSettings { resolution: Some([3, 3, 3]), update_rule: rule, ..Default::default() };
    GaussianMixture::new(Vec3::NEG_ONE, Vec3::ONE, settings).expect("mixture over the box")
}

/// Lobe means of [`GuideAccess::set_entries`] on a mixture: spread over the sphere.
const ENTRY_LOBE_MEANS: [Vec3; 8] = [
    Vec3::new(0.0, 1.0, 0.0),
    Vec3::new(0.8, 0.5, 0.3),
    Vec3::new(-0.6, 0.2, 0.7),
    Vec3::new(0.1, -0.9, -0.4),
    Vec3::new(-0.5, 0.6, -0.6),
    Vec3::new(0.7, -0.3, -0.6),
    Vec3::new(-0.9, -0.4, 0.1),
    Vec3::new(0.3, 0.2, -0.9),
];

/// Lobe concentrations of the same: from nearly uniform to about 5° wide.
const ENTRY_LOBE_CONCENTRATIONS: [f32; 8] = [0.5, 4.0, 15.0, 60.0, 250.0, 2.0, 30.0, 120.0];

impl GuideAccess for GaussianMixture {
    fn test_points(&self) -> Vec<(Vec3, Vec3)> {
        box_test_points()
    }

    fn with_budget(budget_bytes: usize) -> Self {
        let settings = GaussianMixtureSettings { budget_bytes, ..Default::default() };
        GaussianMixture::new(Vec3::NEG_ONE, Vec3::ONE, settings).expect("mixture over the box")
    }

    fn entry_count(&self) -> usize {
        self.settings().lobes
    }

    /// Lobe k at a fixed mean and concentration carrying mass `values[k]`.
    fn set_entries(&mut self, region: MixtureRegion, values: &[f32]) {
        let lobes: Vec<(VmfLobe, f32)> = values
            .iter()
            .enumerate()
            .map(|(k, &v)| (VmfLobe::new(ENTRY_LOBE_MEANS[k], ENTRY_LOBE_CONCENTRATIONS[k]), v))
            .collect();
        let total = values.iter().map(|&v| v as f64).sum::<f64>().min(f32::MAX as f64) as f32;
        self.set_mixture(region.index as usize, VmfMixture::from_lobes(&lobes, total));
    }

    fn all_values(&self) -> Vec<f32> {
        (0..self.region_count()).flat_map(|r| self.mixture(r).lobe_weight_statistics().to_vec()).collect()
    }

    fn floor(&self) -> f32 {
        0.0
    }

    fn integration_depth(&self) -> u32 {
        3
    }
}

/// A spatial × directional tree over [`box_walls`]' box with the given rule (one leaf
/// until it learns).
pub fn spatial_directional_tree(rule: UpdateRule) -> SpatialDirectionalTree {
    // The second moment (the default) wherever the rule allows it.
    let settings = SpatialDirectionalTreeSettings::default().with_update_rule(rule);
    SpatialDirectionalTree::new(Vec3::NEG_ONE, Vec3::ONE, settings).expect("tree over the box")
}

/// Levels of the full quadtree [`GuideAccess::set_entries`] gives a tree's leaf.
pub const TREE_ENTRY_DEPTH: u32 = 3;

impl GuideAccess for SpatialDirectionalTree {
    fn test_points(&self) -> Vec<(Vec3, Vec3)> {
        box_test_points()
    }

    fn with_budget(budget_bytes: usize) -> Self {
        let settings = SpatialDirectionalTreeSettings { budget_bytes, ..Default::default() };
        SpatialDirectionalTree::new(Vec3::NEG_ONE, Vec3::ONE, settings).expect("tree over the box")
    }

    fn entry_count(&self) -> usize {
        1 << (2 * TREE_ENTRY_DEPTH)
    }

    /// The leaf's quadtree becomes a full tree of 4³ cells holding `values` as flux.
    fn set_entries(&mut self, region: TreeRegion, values: &[f32]) {
        self.set_leaf_cells(region, TREE_ENTRY_DEPTH, values);
    }

    /// Every leaf's learned flux (its cells' shares are probabilities, checked by
    /// `validate`).
    fn all_values(&self) -> Vec<f32> {
        (0..self.leaf_count() as u32).map(|leaf| self.leaf_flux(leaf)).collect()
    }

    fn floor(&self) -> f32 {
        0.0
    }
}

/// A distribution that samples like `inner` but reports the pdf of `inner` rotated by
/// `angle` about `axis`: a deliberately wrong pdf that still integrates to one.
pub struct RotatedPdf<D> {
    pub inner: D,
    pub frame: Frame,
    pub angle: f32,
}

impl<D: DirectionalDistribution> RotatedPdf<D> {
    fn rotated(&self, d: Vec3) -> Vec3 {
        let local = self.frame.to_local(d);
        let (s, c) = self.angle.sin_cos();
        self.frame.to_world(Vec3::new(c * local.x - s * local.y, s * local.x + c * local.y, local.z))
    }
}

impl<D: DirectionalDistribution> DirectionalDistribution for RotatedPdf<D> {
    fn sample(&self, u: Vec2) -> DirectionSample {
        let s = self.inner.sample(u);
        DirectionSample { direction: s.direction, pdf: self.pdf(s.direction) }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        self.inner.pdf(self.rotated(direction))
    }
}
