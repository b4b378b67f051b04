//! The directional guide of the guided methods: any of guiding-core's Q structures,
//! chosen on the command line, built over the scene and handed to the tracer as a
//! concrete [`Guide`] type (the tracer is generic; this enum only picks the instance).

use guiding_core::volume::SphereLayout;
use guiding_core::{
    GaussianMixture, GaussianMixtureSettings, Guide, GuideStats, HemisphereGrid, HemisphereGridSettings,
    IntegralEstimator, IrradianceVolume, IrradianceVolumeSettings, SpatialDirectionalTree,
    SpatialDirectionalTreeSettings, UpdateRule,
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
    /// Every structure, in the order the command line lists them.
    pub const ALL: [GuideStructure; 4] =
        [GuideStructure::Hemisphere, GuideStructure::Volume, GuideStructure::Mixture, GuideStructure::Tree];

    /// The command line's names of every structure, comma-separated.
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

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
        Self::ALL
            .into_iter()
            .find(|structure| structure.name() == s)
            .ok_or_else(|| format!("unknown guide structure `{s}` ({})", Self::names()))
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

/// What a front end (the command line) chose for the directional guides, from which
/// [`DirectionalGuideSettings::from_choices`] builds any structure's settings; each
/// `None` keeps the structure's own default.
#[derive(Clone, Copy, Debug)]
pub struct GuideChoices {
    /// The hemisphere grid's settings as chosen: its own, and the budget, patches,
    /// update rule, initial Q and uniform mix the volume and the mixture take from it.
    pub hemisphere: HemisphereGridSettings,
    /// The estimator of Eq. (1)'s integral, where one was chosen.
    pub integral: Option<IntegralEstimator>,
    /// Whether the grid learns from the path's own continuation unless an integral was
    /// chosen (guided without next-event estimation; the bidirectional methods).
    pub continuation_by_default: bool,
    /// Q of every entry before learning (radiance), where chosen.
    pub initial_q: Option<f32>,
    /// The share of each distribution spread uniformly, where chosen.
    pub uniform_mix: Option<f32>,
    /// Lobes per mixture.
    pub mixture_lobes: usize,
    /// The tree's own.
    pub tree: TreeChoices,
}

/// What was chosen for the spatial × directional tree; each `None` keeps guiding-core's
/// default.
#[derive(Clone, Copy, Debug)]
pub struct TreeChoices {
    /// Memory budget, bytes.
    pub budget_bytes: usize,
    /// The spatial split constant c.
    pub threshold: Option<f32>,
    /// The directional split share ρ of a leaf's flux.
    pub flux_fraction: Option<f32>,
    /// Whether distributions fold onto the normal's hemisphere.
    pub fold: Option<bool>,
    /// The mixed-normal share that splits a leaf.
    pub mixed_share: Option<f32>,
    /// Whether an aligned normal's half is sampled by density × cos θ.
    pub cosine: Option<bool>,
    /// Whether there is one spatial tree per world axis.
    pub per_axis: Option<bool>,
    /// Whether directions are fitted to the root mean square of what arrives.
    pub second_moment: Option<bool>,
}

impl DirectionalGuideSettings {
    /// The settings of `structure` from what was `chosen`, checked (an error names the
    /// structure and what is wrong).
    pub fn from_choices(structure: GuideStructure, chosen: &GuideChoices) -> Result<Self, String> {
        let hemisphere = chosen.hemisphere;
        Ok(match structure {
            GuideStructure::Hemisphere if chosen.integral.is_none() && chosen.continuation_by_default => {
                let integral = IntegralEstimator::PathContinuation;
                HemisphereGridSettings { update_rule: UpdateRule { integral, ..hemisphere.update_rule }, ..hemisphere }
                    .into()
            }
            GuideStructure::Hemisphere => hemisphere.into(),
            GuideStructure::Volume => {
                let defaults = IrradianceVolumeSettings::default();
                let settings = IrradianceVolumeSettings {
                    budget_bytes: hemisphere.budget_bytes,
                    layout: SphereLayout { resolution: hemisphere.layout.resolution },
                    update_rule: hemisphere.update_rule,
                    initial_q: chosen.initial_q.unwrap_or(defaults.initial_q),
                    uniform_mix: chosen.uniform_mix.unwrap_or(defaults.uniform_mix),
                    ..defaults
                };
                settings.validate().map_err(|e| format!("volume guide: {e}"))?;
                settings.into()
            }
            GuideStructure::Mixture => {
                let defaults = GaussianMixtureSettings::default();
                let settings = GaussianMixtureSettings {
                    budget_bytes: hemisphere.budget_bytes,
                    lobes: chosen.mixture_lobes,
                    update_rule: hemisphere.update_rule,
                    initial_q: chosen.initial_q.unwrap_or(defaults.initial_q),
                    uniform_mix: chosen.uniform_mix.unwrap_or(defaults.uniform_mix),
                    ..defaults
                };
                settings.validate().map_err(|e| format!("mixture guide: {e}"))?;
                settings.into()
            }
            GuideStructure::Tree => {
                let tree = &chosen.tree;
                let integral =
                    chosen.integral.unwrap_or(SpatialDirectionalTreeSettings::default().update_rule.integral);
                // The second moment by default where the integral allows it; asked for
                // with another, the settings' check names the clash.
                let learning_rate = hemisphere.update_rule.learning_rate;
                let defaults =
                    SpatialDirectionalTreeSettings::default().with_update_rule(UpdateRule { learning_rate, integral });
                let settings = SpatialDirectionalTreeSettings {
                    budget_bytes: tree.budget_bytes,
                    uniform_mix: chosen.uniform_mix.unwrap_or(defaults.uniform_mix),
                    spatial_threshold: tree.threshold.unwrap_or(defaults.spatial_threshold),
                    flux_fraction: tree.flux_fraction.unwrap_or(defaults.flux_fraction),
                    fold_to_hemisphere: tree.fold.unwrap_or(defaults.fold_to_hemisphere),
                    mixed_normal_share: tree.mixed_share.unwrap_or(defaults.mixed_normal_share),
                    cosine_product: tree.cosine.unwrap_or(defaults.cosine_product),
                    trees_per_axis: tree.per_axis.unwrap_or(defaults.trees_per_axis),
                    second_moment: tree.second_moment.unwrap_or(defaults.second_moment),
                    ..defaults
                };
                settings.validate().map_err(|e| format!("tree guide: {e}"))?;
                settings.into()
            }
        })
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
