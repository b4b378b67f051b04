//! The directional guide of the guided methods: any of guiding-core's Q structures,
//! chosen on the command line, built over the scene and handed to the tracer as a
//! concrete [`Guide`] type (the tracer is generic; this enum only picks the instance).

use guiding_core::{
    GaussianMixture, GaussianMixtureSettings, Guide, GuideStats, HemisphereGrid, HemisphereGridSettings,
    IrradianceVolume, IrradianceVolumeSettings, SpatialDirectionalTree, SpatialDirectionalTreeSettings,
};

use crate::scene::Scene;

/// Code that runs with a guide's concrete structure: [`DirectionalGuide::visit`] hands
/// it the guide, and W (a guide of the same structure) where there is one, as that
/// structure's own type. This is the one place outside the structures themselves that
/// the tracer's generic code meets the set of structures.
pub trait GuideVisitor {
    /// What the visit gives back.
    type Output;
    /// Runs with the guide `guide` and W `importance`, both of structure `G`.
    fn visit<G: Guide>(self, guide: &mut G, importance: Option<&mut G>) -> Self::Output;
}

/// Which Q structure guides directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GuideStructure {
    /// Probes on the surfaces, each with a hemisphere of equal-area patches.
    Hemisphere,
    /// Full-sphere tables at the leaves of an adaptive octree, found by position.
    Volume,
    /// A grid of cells, each with a von Mises–Fisher mixture over the sphere.
    Mixture,
    /// A spatial binary tree whose leaves hold directional quadtrees, both adaptive.
    Tree,
}

impl GuideStructure {
    /// The command line's name for it.
    pub fn name(self) -> &'static str {
        match self {
            GuideStructure::Hemisphere => "hemisphere",
            GuideStructure::Volume => "volume",
            GuideStructure::Mixture => "mixture",
            GuideStructure::Tree => "tree",
        }
    }

    /// Parses [`name`](Self::name)'s output.
    pub fn from_name(s: &str) -> Result<Self, String> {
        match s {
            "hemisphere" => Ok(GuideStructure::Hemisphere),
            "volume" => Ok(GuideStructure::Volume),
            "mixture" => Ok(GuideStructure::Mixture),
            "tree" => Ok(GuideStructure::Tree),
            _ => Err(format!("unknown guide structure `{s}` (hemisphere, volume, mixture, tree)")),
        }
    }
}

/// The settings of the structure to build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DirectionalGuideSettings {
    /// A [`HemisphereGrid`].
    Hemisphere(HemisphereGridSettings),
    /// An [`IrradianceVolume`] over the scene's bounds.
    Volume(IrradianceVolumeSettings),
    /// A [`GaussianMixture`] over the scene's bounds.
    Mixture(GaussianMixtureSettings),
    /// A [`SpatialDirectionalTree`] over the scene's bounds.
    Tree(SpatialDirectionalTreeSettings),
}

impl From<SpatialDirectionalTreeSettings> for DirectionalGuideSettings {
    fn from(settings: SpatialDirectionalTreeSettings) -> Self {
        DirectionalGuideSettings::Tree(settings)
    }
}

impl From<IrradianceVolumeSettings> for DirectionalGuideSettings {
    fn from(settings: IrradianceVolumeSettings) -> Self {
        DirectionalGuideSettings::Volume(settings)
    }
}

impl From<HemisphereGridSettings> for DirectionalGuideSettings {
    fn from(settings: HemisphereGridSettings) -> Self {
        DirectionalGuideSettings::Hemisphere(settings)
    }
}

impl From<GaussianMixtureSettings> for DirectionalGuideSettings {
    fn from(settings: GaussianMixtureSettings) -> Self {
        DirectionalGuideSettings::Mixture(settings)
    }
}

/// A built directional guide.
pub enum DirectionalGuide {
    /// Probes with hemispheres of patches (boxed: the grid's lookup tables make it the
    /// largest variant by far).
    Hemisphere(Box<HemisphereGrid>),
    /// Octree leaves with full-sphere tables.
    Volume(IrradianceVolume),
    /// Cells with vMF mixtures.
    Mixture(GaussianMixture),
    /// Spatial leaves with directional quadtrees.
    Tree(SpatialDirectionalTree),
}

impl DirectionalGuide {
    /// Builds the structure `settings` names over `scene`.
    pub fn build(scene: &Scene, settings: DirectionalGuideSettings) -> Result<Self, String> {
        match settings {
            DirectionalGuideSettings::Hemisphere(settings) => HemisphereGrid::build(&scene.triangles, settings)
                .map(|grid| DirectionalGuide::Hemisphere(Box::new(grid)))
                .map_err(|e| format!("hemisphere guide: {e}")),
            DirectionalGuideSettings::Volume(settings) => {
                let (low, high) = scene.bounds();
                IrradianceVolume::new(low, high, settings)
                    .map(DirectionalGuide::Volume)
                    .map_err(|e| format!("volume guide: {e}"))
            }
            DirectionalGuideSettings::Mixture(settings) => {
                let (low, high) = scene.bounds();
                GaussianMixture::new(low, high, settings)
                    .map(DirectionalGuide::Mixture)
                    .map_err(|e| format!("mixture guide: {e}"))
            }
            DirectionalGuideSettings::Tree(settings) => {
                let (low, high) = scene.bounds();
                SpatialDirectionalTree::new(low, high, settings)
                    .map(DirectionalGuide::Tree)
                    .map_err(|e| format!("tree guide: {e}"))
            }
        }
    }

    /// Runs `visitor` with this guide and W (`importance`, used only where it is of the
    /// same structure) as their concrete type.
    pub fn visit<V: GuideVisitor>(&mut self, importance: Option<&mut DirectionalGuide>, visitor: V) -> V::Output {
        match self {
            DirectionalGuide::Hemisphere(guide) => {
                let importance = match importance {
                    Some(DirectionalGuide::Hemisphere(w)) => Some(w.as_mut()),
                    _ => None,
                };
                visitor.visit(guide.as_mut(), importance)
            }
            DirectionalGuide::Volume(guide) => {
                let importance = match importance {
                    Some(DirectionalGuide::Volume(w)) => Some(w),
                    _ => None,
                };
                visitor.visit(guide, importance)
            }
            DirectionalGuide::Mixture(guide) => {
                let importance = match importance {
                    Some(DirectionalGuide::Mixture(w)) => Some(w),
                    _ => None,
                };
                visitor.visit(guide, importance)
            }
            DirectionalGuide::Tree(guide) => {
                let importance = match importance {
                    Some(DirectionalGuide::Tree(w)) => Some(w),
                    _ => None,
                };
                visitor.visit(guide, importance)
            }
        }
    }

    /// Which structure it is.
    pub fn structure(&self) -> GuideStructure {
        match self {
            DirectionalGuide::Hemisphere(_) => GuideStructure::Hemisphere,
            DirectionalGuide::Volume(_) => GuideStructure::Volume,
            DirectionalGuide::Mixture(_) => GuideStructure::Mixture,
            DirectionalGuide::Tree(_) => GuideStructure::Tree,
        }
    }

    /// Its learned state: guiding-core's byte image of its structure.
    pub fn to_bytes(&self) -> Vec<u8> {
        match self {
            DirectionalGuide::Hemisphere(guide) => guide.to_bytes(),
            DirectionalGuide::Volume(guide) => guide.to_bytes(),
            DirectionalGuide::Mixture(guide) => guide.to_bytes(),
            DirectionalGuide::Tree(guide) => guide.to_bytes(),
        }
    }

    /// A guide of `structure` read from [`to_bytes`](Self::to_bytes)' output; damaged
    /// or foreign bytes give guiding-core's error, naming the field.
    pub fn from_bytes(structure: GuideStructure, bytes: &[u8]) -> Result<Self, String> {
        let named = |e: guiding_core::Error| format!("{} guide: {e}", structure.name());
        Ok(match structure {
            GuideStructure::Hemisphere => {
                DirectionalGuide::Hemisphere(Box::new(HemisphereGrid::from_bytes(bytes).map_err(named)?))
            }
            GuideStructure::Volume => DirectionalGuide::Volume(IrradianceVolume::from_bytes(bytes).map_err(named)?),
            GuideStructure::Mixture => DirectionalGuide::Mixture(GaussianMixture::from_bytes(bytes).map_err(named)?),
            GuideStructure::Tree => DirectionalGuide::Tree(SpatialDirectionalTree::from_bytes(bytes).map_err(named)?),
        })
    }

    /// Adds what `other` learned: both must hold the same structure built over the same
    /// scene with the same settings (guiding-core's `Guide::merge`). Hemisphere grids
    /// merge exactly under the simple average; volumes and trees into the union of their
    /// subdivisions (exact where their shapes agree); mixtures by pairing lobes
    /// (approximate).
    pub fn merge(&mut self, other: &DirectionalGuide) -> Result<(), String> {
        let name = self.structure().name();
        let failed = |e: guiding_core::Error| format!("merging {name} guides: {e}");
        match (self, other) {
            (DirectionalGuide::Hemisphere(grid), DirectionalGuide::Hemisphere(other)) => {
                grid.merge(other).map_err(failed)
            }
            (DirectionalGuide::Volume(volume), DirectionalGuide::Volume(other)) => volume.merge(other).map_err(failed),
            (DirectionalGuide::Mixture(mixture), DirectionalGuide::Mixture(other)) => {
                mixture.merge(other).map_err(failed)
            }
            (DirectionalGuide::Tree(tree), DirectionalGuide::Tree(other)) => tree.merge(other).map_err(failed),
            (this, other) => Err(format!(
                "cannot merge a {} guide into a {} guide",
                other.structure().name(),
                this.structure().name()
            )),
        }
    }

    /// Its counters and size.
    pub fn stats(&self) -> GuideStats {
        match self {
            DirectionalGuide::Hemisphere(guide) => guide.stats(),
            DirectionalGuide::Volume(guide) => guide.stats(),
            DirectionalGuide::Mixture(guide) => guide.stats(),
            DirectionalGuide::Tree(guide) => guide.stats(),
        }
    }

    /// One line for the plan: what it is and its size.
    pub fn describe(&self) -> String {
        let stats = self.stats();
        match self {
            DirectionalGuide::Hemisphere(_) => format!(
                "hemisphere grid: {} probes × {} patches, {} KiB",
                stats.regions,
                stats.entries_per_region,
                stats.memory_bytes >> 10
            ),
            DirectionalGuide::Volume(guide) => {
                let [x, y, z] = guide.resolution();
                format!(
                    "volume: {x}×{y}×{z} cells growing to {} KiB, {} leaves × {} patches, {} KiB",
                    guide.settings().budget_bytes >> 10,
                    stats.regions,
                    stats.entries_per_region,
                    stats.memory_bytes >> 10
                )
            }
            DirectionalGuide::Mixture(guide) => {
                let [x, y, z] = guide.resolution();
                format!(
                    "mixture: {x}×{y}×{z} cells, {} regions × {} vMF lobes, {} KiB",
                    stats.regions,
                    stats.entries_per_region,
                    stats.memory_bytes >> 10
                )
            }
            DirectionalGuide::Tree(guide) => format!(
                "tree: {} leaves, {} directional nodes, {} KiB of {} KiB",
                guide.leaf_count(),
                guide.directional_node_count(),
                stats.memory_bytes >> 10,
                guide.settings().budget_bytes >> 10
            ),
        }
    }
}
