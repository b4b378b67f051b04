//! The settings of a path.

use super::method::{EnvironmentSampling, LightSelection, Method};

/// Settings of a path.
#[derive(Clone, Copy, Debug)]
pub struct IntegratorSettings {
    /// The estimator.
    pub method: Method,
    /// Most scattering vertices per path.
    pub max_depth: u32,
    /// Russian roulette starts after this many vertices.
    pub rr_depth: u32,
    /// Probability of sampling the guide instead of the BSDF where a guide region exists.
    pub guide_probability: f32,
    /// Only the first this many vertices of a path use the guide (locate, sample, pdf);
    /// deeper ones scatter by the BSDF alone and pass their targets back to the last
    /// guided vertex, which still learns all it would.
    pub guide_depth: u32,
    /// Probability of aiming at the focal guide's boxes instead (where it has any), in
    /// [0, 1 − guide_probability]; 0 leaves focal guiding out.
    pub focal_probability: f32,
    /// Share of paths, drawn at random, that the focal guide learns from, in (0, 1]: its
    /// records (atomic adds into shared octree leaves and selection cells, and a focal
    /// pdf per arrival) cost more than most vertices need, and a quarter of a pass's
    /// paths still teach it plenty.
    pub focal_learning_share: f32,
    /// Whether the directional guide's share is learned per region (up to
    /// `guide_probability`; where it learns 0 the guide is not even located) instead of
    /// `guide_probability` everywhere.
    pub learned_guide_share: bool,
    /// Whether the directional guide learns each direction with the density it was drawn
    /// with (`Guide::update_sampled`: the tables' entries then learn their mean over
    /// their solid angle) or without (`Guide::update`). The GPU tracer's tables learn
    /// without; the CPU renders checked against them turn this off.
    pub density_weighted_learning: bool,
    /// Whether MIS between next-event estimation and scattering weighs a direction by the
    /// scattering mixture with the guide's density in it (the power heuristic of the
    /// two strategies' actual densities, a guide pdf per light sample) or by the BSDF's
    /// share of the mixture alone (weights that still sum to one with the light's, so
    /// the image stays unbiased, and no guide lookup per light sample). The GPU tracer
    /// weighs with the guide; the CPU renders checked against its tables do too.
    pub nee_weighs_guide: bool,
    /// Whether the guides take over only a material's diffuse lobes (a plastic's base,
    /// its coat left to the BSDF at its own probability) or its whole sampling.
    pub guide_diffuse_lobes: bool,
    /// With `guide_diffuse_lobes`: conductors at least this rough (GGX α) are guided,
    /// smoother ones left to their BSDF (a narrow lobe the guides cannot follow).
    pub guide_min_alpha: f32,
    /// The focal guide aims also at the lights' mirror images behind flat conductors at
    /// most this rough (GGX α; below 0: none), [`crate::mirror_images`].
    pub focal_mirror_alpha: f32,
    /// Whether guided paths update the guide.
    pub learn: bool,
    /// Whether the guided method without next-event estimation (`Method::Guided`) runs
    /// it in learning passes all the same ("kickstart", as Practical Path Guiding's
    /// implementation offers): those passes' images gain its light samples (MIS-weighted,
    /// unbiased), and the guides learn the full incident radiance from them, lights
    /// included, which the frozen passes then sample without next-event estimation.
    pub nee_kickstart: bool,
    /// How next-event estimation picks an area light.
    pub light_selection: LightSelection,
    /// How next-event estimation samples the environment.
    pub environment_sampling: EnvironmentSampling,
    /// bdpt's connection roulette, as a share of the image's mean luminance so far: a
    /// connection whose weighted contribution, if unblocked, is fainter than this share
    /// of it traces its shadow ray only with probability in proportion (and counts by
    /// the inverse: unbiased). 0 traces every connection.
    pub connection_roulette: f32,
    /// bdpt-guided: whether the light subpaths are guided by W too (else the camera
    /// subpaths alone, by Q).
    pub guide_light_subpaths: bool,
    /// vpl: light subpaths traced per pass for the virtual point lights.
    pub vpl_paths: u32,
    /// vpl: the least distance at which a virtual light's 1/d² is taken, as a share of
    /// the scene's extent (the clamp, and the bias it brings).
    pub vpl_min_distance: f32,
    /// How a camera path decides to end: by its throughput past `rr_depth`, or (guided
    /// methods) by what its continuation is learned to be worth against its cost.
    pub roulette: Roulette,
    /// With the efficiency-aware roulette: whether a path whose continuation is worth
    /// more than it costs splits into up to 4 copies there (else it only goes on).
    pub splitting: bool,
    /// Camera paths in flight together per thread (`nee` only, see
    /// [`PathTracer::traces_in_lanes`](super::PathTracer::traces_in_lanes)): their rays
    /// traced as a batch (Embree's 16-ray packets) and their vertices shaded one lane
    /// after another. 1 traces one path at a time. Each path draws from its own pixel's
    /// generator as alone, so the image does not depend on it.
    pub lanes: u32,
}

/// How a camera path decides to end (`--roulette`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Roulette {
    /// Past `rr_depth` vertices, survive with the throughput (at most 0.95).
    #[default]
    Throughput,
    /// Efficiency-aware (guided methods): learned in the training passes per cell side of
    /// a grid `cells` along the scene's longest side (guiding-core's
    /// `EfficiencyRoulette`); in the passes that do not learn, at every vertex survive
    /// with what the continuation's second moment is worth against its cost and the
    /// image's variance; by the throughput where nothing is learned yet, and in learning
    /// passes.
    Efficiency {
        /// Cells along the scene's longest side, 1..=128.
        cells: u32,
    },
}

/// [`IntegratorSettings::lanes`] by default (`--lanes`): one path at a time, until the
/// guided methods run in lanes too. In 16 lanes (Embree's packet width) nee traces, on
/// one thread, door 160×120 0.66–0.67 M paths/s against 0.58 M, cornell 128² 1.05–1.08 M
/// against 0.96 M; with nee alone faster, the guided methods' equal-time figures against
/// it would move by the speed-up, not by what guiding does.
pub const DEFAULT_LANES: u32 = 1;

/// [`IntegratorSettings::vpl_paths`] by default.
pub const DEFAULT_VPL_PATHS: u32 = 64;

/// Smoothest conductor (GGX α) the command line guides by default (`--guide-min-alpha`).
pub const DEFAULT_GUIDE_MIN_ALPHA: f32 = 0.3;
/// [`IntegratorSettings::vpl_min_distance`] by default.
pub const DEFAULT_VPL_MIN_DISTANCE: f32 = 0.02;

/// [`IntegratorSettings::connection_roulette`] by default.
pub const DEFAULT_CONNECTION_ROULETTE: f32 = 0.0;

impl Default for IntegratorSettings {
    fn default() -> Self {
        Self {
            method: Method::Nee,
            max_depth: 32,
            rr_depth: 4,
            guide_probability: 0.3,
            guide_depth: u32::MAX,
            focal_probability: 0.0,
            focal_learning_share: 0.25,
            learned_guide_share: false,
            density_weighted_learning: true,
            nee_weighs_guide: false,
            guide_diffuse_lobes: false,
            guide_min_alpha: 0.0,
            focal_mirror_alpha: -1.0,
            learn: true,
            nee_kickstart: false,
            light_selection: LightSelection::Power,
            environment_sampling: EnvironmentSampling::Luminance,
            connection_roulette: DEFAULT_CONNECTION_ROULETTE,
            guide_light_subpaths: true,
            vpl_paths: DEFAULT_VPL_PATHS,
            vpl_min_distance: DEFAULT_VPL_MIN_DISTANCE,
            roulette: Roulette::Throughput,
            splitting: false,
            lanes: DEFAULT_LANES,
        }
    }
}
