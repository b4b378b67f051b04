//! The tracing options every rendering command shares, and their parsers.

use crate::mirror_images::DEFAULT_FOCAL_MIRROR_ALPHA;
use crate::scene_intersector::IntersectorChoice;
use clap::Args;
use guiding_core::{HemisphereMapping, IntegralEstimator, LearningRate, LightUpdateRule};

use crate::backend::Device;
use crate::directional_guide::GuideStructure;
use crate::film::Combine;
use crate::integrator::{EnvironmentSampling, LightSelection, Method};
use crate::lights::MAX_LIGHT_SPLIT;
use crate::schedule::Schedule;

/// `--resolution`: W×H within the largest image side.
pub(super) fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let [width, height] = parse_patches(s)?;
    let limit = crate::scene::MAX_IMAGE_SIDE;
    if width == 0 || height == 0 || width > limit || height > limit {
        return Err(format!("`{s}`: each side must be in 1..={limit}"));
    }
    Ok([width, height])
}

pub use crate::session::GUIDE_SHARE_COST;

/// The command line's selection cells along the scene's longest side (`--focal-cells`).
pub const FOCAL_CELLS: u32 = 16;

/// How the directional guide's share of the scattering is set (`--guide-share`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GuideShare {
    /// `--p-guide` at every guided vertex.
    #[default]
    Fixed,
    /// Learned per region, up to `--p-guide`.
    Learned,
}

impl GuideShare {
    /// Parses `fixed` or `learned`.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "fixed" => Ok(GuideShare::Fixed),
            "learned" => Ok(GuideShare::Learned),
            _ => Err(format!("unknown guide share `{name}` (fixed, learned)")),
        }
    }
}

/// Options shared by every command that traces paths.
#[derive(Debug, Args, Clone)]
pub struct TraceOptions {
    /// The directional guide of the guided methods: auto (a hemisphere grid unless every
    /// surface is a mirror or glass; see the printed plan), hemisphere (probes with
    /// hemispheres of patches), volume (full-sphere tables in an adaptive octree),
    /// mixture (grid cells with vMF mixtures), tree (a spatial binary tree of
    /// directional quadtrees), or none. compare
    /// takes several, comma-separated, and runs each guided method with each.
    #[arg(long, default_value = "auto", value_delimiter = ',', value_parser = parse_guide_choice)]
    pub(super) guide: Vec<GuideChoice>,
    /// Lobes per mixture (--guide mixture), 1..=8. 2 measured best on door and cornell
    /// (against 3 and 6, 15 s each: fewer lobes cost less per sample).
    #[arg(long, default_value_t = 2)]
    pub(super) mixture_lobes: usize,
    /// Image size W×H instead of the scene's (same vertical field of view), e.g. 320x180.
    #[arg(long, value_parser = parse_resolution)]
    pub(super) resolution: Option<[u32; 2]>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub(super) seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(super) threads: Option<usize>,
    /// Most scattering vertices per path.
    #[arg(long, default_value_t = 32)]
    pub(super) max_depth: u32,
    /// Russian roulette after this many vertices.
    #[arg(long, default_value_t = 4)]
    pub(super) rr_depth: u32,
    /// Probability of sampling the guide instead of the BSDF, in [0, 1]: with the learned
    /// share (the CPU's default) the most any region takes. Default 0.5 on the CPU: against
    /// 0.3, guided-nee relMSE × spp at 30 s, seeds 41 and 42, cornell 128² 0.154/0.153
    /// against 0.167/0.162, door 160×120 11.77/11.18 against 11.44/11.17, glossy 128²
    /// 17.63/16.90 against 17.93/16.98; Veach Ajar relMSE at 60 s 3.61/3.18 against
    /// 3.43/3.26. 0.3 on the GPU, whose share is fixed at every vertex (0.5 compounds
    /// larger mixture weights over bounces).
    #[arg(long)]
    pub(super) p_guide: Option<f32>,
    /// Only the first N vertices of each path use the guide; deeper ones sample the BSDF
    /// alone, at nee's cost per vertex. Default 1 on the CPU for guided-nee (every vertex for
    /// guided, which has no light samples to lean on), measured best: guided-nee ÷
    /// nee at 20 s on cornell 128² 1.01–1.09 (every vertex: 1.29), on door 160×120 1.21
    /// (every vertex: 1.45; 2: 1.16). The GPU tracer guides every vertex.
    #[arg(long)]
    pub(super) guide_depth: Option<u32>,
    /// Most probability of aiming at the focal guide (points in space where light squeezes
    /// through, learned from the segments that carried it) instead of the BSDF, at every
    /// vertex of a guided method; each region of space learns its own share up to it (the
    /// least variance among 0, 0.02, … 0.5, --focal-share-cost); p_guide + p_focal ≤ 1. 0 leaves it out.
    /// Default 0.5 (at most 1 − p_guide) on the CPU for guided-nee, 0.25 for guided (see
    /// --nee-kickstart), 0 on the GPU (which has no focal guide). 0.5 with `--guide none --p-guide 0 --schedule iterative`, at 60 s: door
    /// 160×120 0.57–0.60 × nee's relMSE, cornell 128² 1.02 ×.
    #[arg(long)]
    pub(super) p_focal: Option<f32>,
    /// The focal guide's most boxes (its densest leaves), 1..=1024.
    #[arg(long)]
    pub(super) focal_boxes: Option<u32>,
    /// The focal guide's density ratio: a leaf is sampled when its density is at least
    /// this many times the occupied mean.
    #[arg(long)]
    pub(super) focal_ratio: Option<f32>,
    /// The focal guide's split share: a leaf holding more of the mass splits.
    #[arg(long)]
    pub(super) focal_split: Option<f32>,
    /// The focal guide's merge ratio: neighbouring focal leaves whose densities differ by
    /// at most this factor become one box; 0 keeps every leaf its own box.
    #[arg(long)]
    pub(super) focal_merge: Option<f32>,
    /// Points along each recorded segment where the focal guide deposits its mass, 1..=64,
    /// or 0: exactly, into every octree leaf the segment crosses by the length inside.
    /// Default 4: exact deposits measured no better on door 160×120 (30 s, seed 41, relMSE ×
    /// spp 12.3 against 11.9), the octree's leaves staying about as coarse (7–14 cm around
    /// a 1 cm gap) either way.
    #[arg(long)]
    pub(super) focal_deposits: Option<u32>,
    /// Whether each cell of the focal guide's selection grid learns its own probabilities
    /// of the boxes, by what its vertices' light came through (a quarter stays with the
    /// boxes' global masses), rather than every cell drawing them by mass (on, off).
    /// Default on: at 60 s, relMSE on ÷ off, seeds 41 and 42, guided-nee on door 160×120
    /// 0.960 and 0.954 and on Veach Ajar 0.924 and 0.941 (cornell has no boxes); guided
    /// on door 0.736 and 0.462, cornell 128² 1.05, many_lights 160×120 (30 s) 0.720.
    #[arg(long, value_parser = parse_switch)]
    pub(super) focal_boxes_per_cell: Option<bool>,
    /// Share of paths the focal guide learns from, in (0, 1]. 0.25 measured best (60 s,
    /// against 1: cornell 128² ÷ nee 1.02 against 1.06–1.20, its paths/s 0.98 × nee's
    /// against 0.81–0.92; door 160×120 0.60 against 0.57).
    #[arg(long, default_value_t = 0.25)]
    pub(super) focal_learn: f32,
    /// The directional guide's share of the scattering: fixed (--p-guide at every guided
    /// vertex) or learned (each cell of the focal guide's selection grid picks, up to
    /// --p-guide, the share whose estimator had the least variance times its cost
    /// (--guide-share-cost), as the focal guide does; where it picks 0 the guide is not even located). Default learned on
    /// the CPU, fixed on the GPU (which learns no share). With `--guide hemisphere
    /// --schedule iterative --p-guide 0.3 --p-focal 0.5`, 60 s, ÷ nee (seeds 21, 22):
    /// door 160×120 0.494 and 0.486, cornell 128² 0.966 and 1.218 (per sample 0.80 both
    /// times; its paths/s 0.83 and 0.66 of nee's).
    #[arg(long, value_parser = GuideShare::from_name)]
    pub(super) guide_share: Option<GuideShare>,
    /// The selection cells along the scene's longest side, 1..=64: each learns its own
    /// probability of aiming at the focal boxes and its own share of the directional
    /// guide. Default 16 (guiding-core's own default is 8): guided-nee at 60 s, relMSE 16
    /// ÷ 8, seeds 41 and 42, Veach Ajar 0.916 and 0.969, door 160×120 1.032 and 0.949,
    /// cornell 128² 0.974 (seed 41).
    #[arg(long, default_value_t = FOCAL_CELLS)]
    pub(super) focal_cells: u32,
    /// The learned guide share's cost of guiding, ≥ 0: a cell gives the directional guide a
    /// share above 0 only where the variance it leaves, times 1 + this, is below the
    /// variance at 0 (the guide's lookups cost time at every vertex of the cell). 0.3
    /// measured best: against 0, guided-nee at 30 s, relMSE ÷ (seeds 41 and 42), door
    /// 160×120 0.94/0.96 (the focal guide serves it: the guide kept 1 of 96 cells, per
    /// sample equal), glossy 128² 0.97/0.95, many_lights 160×120 0.97/0.98, cornell 128²
    /// 1.01/1.04 (per sample 1.01/1.00); 1 lost 19 % per sample on cornell.
    #[arg(long, default_value_t = GUIDE_SHARE_COST)]
    pub(super) guide_share_cost: f32,
    /// The focal guide's selection cost, ≥ 0, as --guide-share-cost for aiming at the
    /// boxes. Default 0: at 0.1 or 0.3 for both, door 160×120 lost 12 % and 87 % per sample
    /// (30 s, seed 41): where both strategies serve a cell each one's own gain looks small
    /// and both were dropped.
    #[arg(long)]
    pub(super) focal_share_cost: Option<f32>,
    /// Learning rate: simple (α = 1/(1+visits)), region, exponential:ALPHA or global:EXPONENT.
    #[arg(long, default_value = "simple", value_parser = parse_learning_rate)]
    pub(super) learning_rate: LearningRate,
    /// Integral of Eq. (1): sampled (the weighted sum for diffuse surfaces, one BSDF
    /// sample for glossy ones: on Veach Ajar 3× the paths/s of weighted, and a 4.7× lower
    /// relMSE at 30 s), weighted (BSDF-weighted sum over every patch), stratified, max, or
    /// path (the path's own continuation, no lookup). Default: path for the tree and for
    /// the grid under guided, sampled for the others.
    #[arg(long, value_parser = parse_integral)]
    pub(super) integral: Option<IntegralEstimator>,
    /// When guided methods learn: online (every pass, every pass kept) or iterative
    /// (training iterations of 1, 2, 4, … passes with a refit after each, then a frozen
    /// final image; --combine says how the iterations make the image). Default
    /// iterative on the CPU, online on the GPU (which learns online only).
    #[arg(long, value_parser = Schedule::from_name)]
    pub(super) schedule: Option<Schedule>,
    /// How the iterative schedule's iterations make the image: final (the frozen last
    /// one alone), samples (every pass alike, unbiased) or inverse-variance (each
    /// iteration by the inverse of its estimated relative variance, estimated at each
    /// pixel without it, and no sample above one of the latest iteration). Door 160×120,
    /// 30 s, focal guided-nee, relMSE × spp, seeds 11 and 12: samples 12.82 and 12.60,
    /// inverse-variance 12.83 and 12.26, final 10.98 and 10.97 (of fewer samples: relMSE
    /// 1.5 times); cornell 128²: 0.194/0.198 against 0.195/0.200. At f1941ce, guided-nee
    /// (grid) at 60 s, relMSE × spp inverse-variance against samples: door 5.57 against
    /// 5.94, cornell 0.256 against 0.254, living room (tiles) at seeds 41–43 4.54, 4.71
    /// and 4.60 against 4.91, 5.01 and 4.97 (runs of one seed differ by about 4 %); but at
    /// 10 s the living room's relMSE was 1.6 to 1.9 × nee's against 0.97 to 1.52: the
    /// current iteration's first pass was left out of the image. Since it borrows the
    /// iteration before's variance, 1.12 and 0.98 (seeds 42 and 43; at 60 s 4.90 and
    /// 4.76). At 73fffa7 on all six scenes (seed 41, guided-nee at 60 s, relMSE
    /// inverse-variance ÷ samples, at 10 s in brackets): door 0.88 (1.16), cornell 0.99
    /// (1.01), glossy 0.99 (0.94), many_lights 0.97 (0.84), Veach Ajar 0.99 (0.98), living
    /// room 0.97 (1.22): a few per cent at 60 s, within a run's noise but on one scene,
    /// and door and the living room lose at 10 s. Samples stays.
    #[arg(long, default_value = Combine::default().name(), value_parser = Combine::from_name)]
    pub(super) combine: Combine,
    /// The tree guide's memory budget, MiB.
    #[arg(long, default_value_t = 16.0)]
    pub(super) tree_mib: f64,
    /// The tree's spatial split constant c: a leaf splits past c·√R of an epoch's R records.
    #[arg(long)]
    pub(super) tree_threshold: Option<f32>,
    /// The tree's directional split share ρ of a leaf's flux, in (0, 1).
    #[arg(long)]
    pub(super) tree_flux_fraction: Option<f32>,
    /// Whether the tree's distributions fold onto the normal's hemisphere (on, off).
    #[arg(long, value_parser = parse_switch)]
    pub(super) tree_fold: Option<bool>,
    /// The tree's mixed-normal share, in [0, 1]: a leaf also splits when no world axis
    /// holds this share of its records' normals (0: never). Default 0.97 (guiding-core's).
    #[arg(long)]
    pub(super) tree_mixed_share: Option<f32>,
    /// Whether the tree samples an aligned normal's half by its density times cos θ (on,
    /// off). Default on (guiding-core's).
    #[arg(long, value_parser = parse_switch)]
    pub(super) tree_cosine: Option<bool>,
    /// Whether the tree keeps one spatial tree per world axis, for the surfaces whose
    /// normal lies nearest it (on), or one whose leaves turn to their records' normals
    /// (off). Default guiding-core's.
    #[arg(long, value_parser = parse_switch)]
    pub(super) tree_per_axis: Option<bool>,
    /// Whether the tree fits each direction to the root mean square of what arrives
    /// (variance-aware guiding, on) or to its mean (off). Default guiding-core's.
    #[arg(long, value_parser = parse_switch)]
    pub(super) tree_second_moment: Option<bool>,
    /// Patches per hemisphere as U×V, e.g. 8x16 (for --guide volume: bands of cos θ ×
    /// sectors of φ over the whole sphere).
    #[arg(long, default_value = "8x16", value_parser = parse_patches)]
    pub(super) patches: [u32; 2],
    /// cylindrical or concentric.
    #[arg(long, default_value = "cylindrical", value_parser = parse_mapping)]
    pub(super) mapping: HemisphereMapping,
    /// Guide memory budget, MiB. 0.5 measured best on door (the tables stay in the L2
    /// cache) and equal on cornell; guiding-core's own default is 2.
    #[arg(long, default_value_t = 0.5)]
    pub(super) guide_mib: f64,
    /// Q of every patch before learning (radiance).
    #[arg(long)]
    pub(super) initial_q: Option<f32>,
    /// Share of each probe's sampling probability spread uniformly, in [0, 1].
    #[arg(long)]
    pub(super) uniform_mix: Option<f32>,
    /// Largest angle between a hit's normal and its probe's, degrees.
    #[arg(long)]
    pub(super) max_normal_angle: Option<f32>,
    /// Exponent γ of the sampling weights Q^γ, in (0, 1].
    #[arg(long)]
    pub(super) sampling_exponent: Option<f32>,
    /// Whether a probe samples its patches by Q·∫cos (the product with a Lambertian
    /// surface's cosine) rather than by Q alone (on, off). Default on for the CPU: with
    /// `--guide hemisphere --guide-share learned --schedule iterative --p-guide 0.3
    /// --p-focal 0.5`, 30 s, relMSE × spp off → on, seeds 31 and 32: cornell 128² 0.160 →
    /// 0.149 and 0.162 → 0.149, door 160×120 15.67 → 14.92 and 13.99 → 13.79. The GPU
    /// tracer samples by Q alone.
    #[arg(long, value_parser = parse_switch)]
    pub(super) cosine_product: Option<bool>,
    /// Whether the guides take over only a material's diffuse lobes (on: a plastic's
    /// coat keeps the probability its BSDF gives it, so its sharp reflections of bright
    /// windows do not weigh double) or its whole sampling (off). Default on: living room
    /// 1280×720, `--guide-share fixed --train-share 0.5 --combine final`, 120 s, seed 41,
    /// relMSE × spp of the frozen passes 5.61 against 5.91 (nee 5.96); scenes without
    /// plastic render alike either way.
    #[arg(long, value_parser = parse_switch)]
    pub(super) guide_diffuse_lobes: Option<bool>,
    /// Conductors with a GGX α below this are not guided (their BSDF keeps its whole
    /// sampling, the focal guide's included), with `--guide-diffuse-lobes on`. Default 0.3:
    /// Veach Ajar (floor α 0.1, pots 0.15, handles 0.25), guided-nee at 60 s, relMSE 0.963 and
    /// 0.922 times 0's (seeds 41, 42; per sample 0.986 and 0.976, paths/s 1.02 and 1.05
    /// times); glossy 128² (metal α 0.15), 30 s, 1.028 and 0.961 times.
    #[arg(long)]
    pub(super) guide_min_alpha: Option<f32>,
    /// The focal guide aims also at the lights' mirror images behind wide flat conductors
    /// at most this rough (GGX α), where its cells learn that it pays; below 0: none.
    /// Default 0.2: Veach Ajar (floor α 0.1), guided-nee at 60 s, relMSE 1.019 and 1.051
    /// (seeds 41, 42) against 1.25–1.54 without; scenes without such a plane render as
    /// before.
    #[arg(long, default_value_t = DEFAULT_FOCAL_MIRROR_ALPHA, allow_negative_numbers = true, value_parser = parse_finite)]
    pub(super) focal_mirror_alpha: f32,
    /// The guided method without next-event estimation (`guided`) runs it all the same in
    /// its learning passes (on, off): their images gain its light samples, and the guides
    /// learn the full incident radiance, lights included, which the frozen passes then
    /// sample without it (Practical Path Guiding's "kickstart"). Default on for guided on
    /// the CPU, with the guide at every vertex and the focal guide at most 0.25: guided ÷
    /// pt's relMSE at 20 s went from 1.27 to 0.61 on door 160×120, from 0.47 to 0.36 on
    /// cornell 128² and from 0.61 to 0.71 on many_lights 160×120 (seed 41; both seeds
    /// at `without_nee_defaults` in cli/settings.rs). The GPU tracer has none.
    #[arg(long, value_parser = parse_switch)]
    pub(super) nee_kickstart: Option<bool>,
    /// bdpt: trace a connection's shadow ray only with probability c / (this × the image's
    /// mean luminance so far) where its unblocked, unweighted contribution c is fainter
    /// than that, counting it by the inverse (unbiased); 0 traces them all. Default 0: it
    /// pays only where the image is dark against its lights. 20 s, seed 41, relMSE: door
    /// 160×120 0 → 1.66e-2, 0.5 → 1.65e-2, 2 → 1.60e-2, 10 → 1.43e-2, 50 → 1.62e-2 (rays
    /// per sample 38.4 → 21.7 at 10); cornell 128² 0 → 1.12e-4, 10 → 2.56e-3.
    #[arg(long, default_value_t = crate::integrator::DEFAULT_CONNECTION_ROULETTE, value_parser = parse_non_negative)]
    pub(super) connection_roulette: f32,
    /// bdpt-guided: guide the light subpaths by W too (on), or only the camera subpaths by
    /// Q (off). Default on: caustic 128², 20 s, seed 41, relMSE × spp, grid 5.08 (off
    /// 28.5), tree 4.78 (off 6.06); plain bdpt 5.05.
    #[arg(long, value_parser = parse_switch)]
    pub(super) guide_light_subpaths: Option<bool>,
    /// vpl: light subpaths traced per pass; their vertices are the pass's virtual point
    /// lights, each gathered through a shadow ray at every pixel.
    #[arg(long, default_value_t = crate::integrator::DEFAULT_VPL_PATHS, value_parser = clap::value_parser!(u32).range(1..))]
    pub(super) vpl_paths: u32,
    /// vpl: the least distance at which a virtual light's 1/d² is taken, as a share of the
    /// scene's extent: larger removes more of the splotches beside each virtual light and
    /// darkens more of the light exchanged at shorter range (corners); 0 clamps nothing.
    #[arg(long, default_value_t = crate::integrator::DEFAULT_VPL_MIN_DISTANCE, value_parser = parse_non_negative)]
    pub(super) vpl_min_distance: f32,
    /// How camera paths of the guided methods end: throughput (Russian roulette past
    /// --rr-depth by the path's throughput) or efficiency (learned in the training passes
    /// per cell side: in the frozen passes every vertex weighs what its continuation's
    /// light varies by against what going on costs and the image's variance; Rath et al.
    /// 2022). Unguided methods, learning passes and the GPU tracer always use throughput.
    /// Default efficiency for guided-nee and guided on the CPU, else throughput: relMSE
    /// efficiency ÷ throughput, seed 41, guided-nee at 30 s door 160×120 0.63, cornell
    /// 128² 0.97, at 60 s Veach Ajar 0.85, living room 0.76; guided at 30 s door 0.25,
    /// cornell 0.54.
    #[arg(long, value_parser = parse_roulette_kind)]
    pub(super) roulette: Option<RouletteKind>,
    /// --roulette efficiency: whether a path whose continuation is worth more than it
    /// costs splits (into up to 4 copies at a vertex, 16 a path), or only goes on (on,
    /// off). Default off: guided-nee at 30 s, seed 41, on ÷ off, door 160×120 relMSE 1.62
    /// (per sample 0.76, its paths 2.2× as long), cornell 128² 1.27 (per sample 0.53,
    /// 2.8× as long): the costs it learns in the training passes, which do not split,
    /// leave out what splitting adds, and it splits too often.
    #[arg(long, value_parser = parse_switch)]
    pub(super) splitting: Option<bool>,
    /// nee: camera paths in flight together on each thread, their rays traced as one
    /// batch (Embree's 16-ray packets) and their vertices shaded lane after lane; 1 traces
    /// one path at a time. Each path draws its own pixel's random numbers as alone, so the
    /// image is the same to the last bit whatever the lanes (where no light or environment
    /// guide learns from the light samples; with one, the same within noise). 16 traces
    /// 1.11-1.14x the paths/s of one path at a time on door and cornell; default 1 while
    /// only nee runs in lanes.
    #[arg(long, default_value_t = crate::integrator::DEFAULT_LANES, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub(super) lanes: u32,
    /// --roulette efficiency: cells along the scene's longest side, 1..=128. 32 measured
    /// best on the living room 1280×720 (guided-nee with tiles, 60 s, seed 41, one run
    /// each): relMSE × spp over paths/s 1.04e-5 against 1.13e-5 with 16 cells (per
    /// sample 4.91 against 4.68, paths 3.05 vertices long against 3.35) and 1.13e-5 with
    /// 64 (per sample 5.46).
    #[arg(long, default_value_t = 32)]
    pub(super) roulette_cells: u32,
    /// Guided methods: seconds of training passes whose samples are discarded (their
    /// time counts towards --seconds).
    #[arg(long, default_value_t = 0.0)]
    pub(super) train_seconds: f64,
    /// The most of --seconds the iterative schedule trains for, in (0, 1], except that its
    /// second and third iterations may end within twice it (it also stops where the next
    /// doubled iteration would leave the frozen image less than half).
    /// Default 0.15, and 0.5 for guided on the CPU. 0.15 measured best for guided-nee at
    /// 60 s, seed 41, relMSE against 1 (the doubling rule alone): glossy 128² 0.98×, door
    /// 160×120 0.97×, cornell 128² 0.97×, Veach Ajar 0.95×, living room 0.82× (0.3: 0.99×,
    /// 0.99×, 0.97× on the first three). guided, whose frozen passes find the light by
    /// scattering alone, gains from a longer training: 20 s, relMSE ÷ 0.15's, seeds 41 and
    /// 42, 0.5: door 0.81 and 0.90, cornell 0.90 and 0.93 (0.3: 0.97, 0.97, 0.98, 0.89).
    #[arg(long, value_parser = parse_share)]
    pub(super) train_share: Option<f64>,
    /// Ray tracing library: auto (Embree where this lodestar was built with the `embree`
    /// feature, as scripts/render.sh builds it, else obvhs), obvhs (CWBVH), obvhs-bvh2, or
    /// embree. Embree measured 1.16–1.22× obvhs's nee paths/s (cornell 128², door 160×120,
    /// 20 s) and 1.30–1.34× its guided-nee paths/s.
    #[arg(long, default_value = "auto", value_parser = IntersectorChoice::from_name)]
    pub(super) intersector: IntersectorChoice,
    /// Where paths are traced: cpu (all cores), or gpu (a wgpu compute shader on a
    /// Vulkan adapter; needs the `gpu` feature). compare takes gpu:METHOD instead.
    #[arg(long, default_value = "cpu", value_parser = Device::from_name)]
    pub(super) device: Device,
    /// Next-event light selection: auto (learned with many lights, else power; see the
    /// printed plan), uniform, power, or learned (Eq. 3, per grid cell).
    #[arg(long, default_value = "auto", value_parser = parse_light_selection)]
    pub(super) light_selection: Auto<LightSelection>,
    /// Learned selection's rule: mean (occluded rays count as zero), unoccluded (the seed's
    /// Eq. 3: only arriving rays), or visibility (arrived / shot, times power).
    #[arg(long, default_value = "mean", value_parser = parse_light_rule)]
    pub(super) light_rule: LightUpdateRule,
    /// Next-event gate of guided methods (CPU): a grid cell whose share of arriving shadow
    /// rays is v estimates next-event light with probability clamp(SCALE·v, FLOOR, 1), and
    /// otherwise leaves its light to the scattered direction (MIS-weighted alike, so
    /// unbiased). 0 always shoots. 20 measured best: guided-nee relMSE at fixed spp, 20
    /// against 5 (seeds 5 and 6), many_lights 160×120 512 spp 1.87e-3/1.88e-3 against
    /// 2.15e-3/2.18e-3 (ungated 1.82e-3; nee 1.88e-3) with 0.5 % more rays, door 160×120
    /// 256 spp 5.37e-2/5.71e-2 against 5.28e-2/6.12e-2 (ungated 6.18e-2, 1.5 times the
    /// rays), cornell and glossy 128² 512 spp 1 % and 1 % lower. Scale 5 had cut rays on
    /// door and skipped cells on many_lights where few but bright shadow rays arrive.
    #[arg(long, default_value_t = 20.0)]
    pub(super) nee_gate: f32,
    /// The next-event gate's least probability of a shadow ray (FLOOR above), in (0, 1]. 0.03 against
    /// 0.1 on door (30 s, seeds 11 and 12): relMSE 0.89 and 1.04 times, so 0.1 stays.
    #[arg(long, default_value_t = 0.1)]
    pub(super) nee_gate_floor: f32,
    /// Learned selection's memory budget, MiB.
    #[arg(long, default_value_t = 1.0)]
    pub(super) light_guide_mib: f64,
    /// Segments per edge each emissive triangle is cut into for next-event estimation of
    /// guided methods (CPU), each part a light that learned selection picks on its own (so a
    /// region that sees a sliver of a large emitter samples that sliver): 1..=16, or auto
    /// (scenes with few emissive triangles are cut into about 64 lights, at most 8 segments
    /// per edge; see the printed plan). Baselines and the GPU tracer use whole triangles.
    /// 1 measured best at equal time: auto against 1, guided-nee ÷ nee at 60 s, seed 41,
    /// door 160×120 0.526 against 0.443 and cornell 128² 0.954 against 0.922 (per sample
    /// 0.72 against 0.78 of nee's, but the learned selection's cost: paths/s 0.73 of nee's
    /// against 0.84); Veach Ajar 1280×720, guided-nee's relMSE auto ÷ 1 0.97 and 0.84
    /// (seeds 41, 42).
    #[arg(long, default_value = "1", value_parser = parse_light_split)]
    pub(super) light_split: Auto<u32>,
    /// Next-event environment sampling: auto (tiles when there is an environment; see the
    /// printed plan), luminance (plain importance sampling), or tiles (learned per cell).
    #[arg(long, default_value = "auto", value_parser = parse_environment_sampling)]
    pub(super) env_sampling: Auto<EnvironmentSampling>,
    /// Environment tiles across × down the lat-long map. 32x16 measured best on window
    /// (against 8x4, 16x8 and 64x32; 2 seeds × 15 s).
    #[arg(long, default_value = "32x16", value_parser = parse_patches)]
    pub(super) env_tiles: [u32; 2],
    /// Share of each cell's tile probability kept in proportion to power, in [0, 1).
    /// 0.1 measured best on window (against 0.2 and 0.4).
    #[arg(long, default_value_t = 0.1)]
    pub(super) env_power_mix: f32,
    /// Environment-tile guide's memory budget for its per-cell tables, MiB.
    #[arg(long, default_value_t = 1.0)]
    pub(super) env_guide_mib: f64,
}

/// A choice given on the command line, or `None` for `auto` (the plan decides). A
/// newtype, as clap reads a bare `Option` field as "may be absent".
#[derive(Clone, Copy, Debug)]
pub(super) struct Auto<T>(pub(super) Option<T>);

impl<T> Auto<T> {
    pub(super) fn parse(s: &str, parse: impl Fn(&str) -> Result<T, String>) -> Result<Self, String> {
        if s == "auto" {
            Ok(Auto(None))
        } else {
            parse(s).map(|choice| Auto(Some(choice)))
        }
    }
}

pub(super) fn parse_environment_sampling(s: &str) -> Result<Auto<EnvironmentSampling>, String> {
    Auto::parse(s, EnvironmentSampling::from_name)
}

pub(super) fn parse_light_selection(s: &str) -> Result<Auto<LightSelection>, String> {
    Auto::parse(s, LightSelection::from_name)
}

pub(super) fn parse_light_split(s: &str) -> Result<Auto<u32>, String> {
    Auto::parse(s, |s| match s.parse::<u32>() {
        Ok(n) if (1..=MAX_LIGHT_SPLIT).contains(&n) => Ok(n),
        _ => Err(format!("--light-split `{s}` must be auto or a whole number in 1..={MAX_LIGHT_SPLIT}")),
    })
}

/// `--guide`: a structure, `auto` (the default structure) or `none`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GuideChoice {
    Auto,
    Structure(GuideStructure),
    Off,
}

impl GuideChoice {
    /// The structure to build, if any: `auto` is the hemisphere grid.
    pub(super) fn structure(self) -> Option<GuideStructure> {
        match self {
            GuideChoice::Auto => Some(GuideStructure::Hemisphere),
            GuideChoice::Structure(structure) => Some(structure),
            GuideChoice::Off => None,
        }
    }
}

pub(super) fn parse_guide_choice(s: &str) -> Result<GuideChoice, String> {
    match s {
        "auto" => Ok(GuideChoice::Auto),
        "none" => Ok(GuideChoice::Off),
        _ => GuideStructure::from_name(s).map(GuideChoice::Structure),
    }
}

pub(super) fn parse_light_rule(s: &str) -> Result<LightUpdateRule, String> {
    match s {
        "mean" => Ok(LightUpdateRule::MeanContribution),
        "unoccluded" => Ok(LightUpdateRule::UnoccludedAverage),
        "visibility" => Ok(LightUpdateRule::VisibilityRatio),
        _ => Err(format!("unknown light rule `{s}` (mean, unoccluded, visibility)")),
    }
}

pub(super) fn parse_method(s: &str) -> Result<Method, String> {
    Method::from_name(s).ok_or_else(|| {
        format!("unknown integrator `{s}` (pt, nee, guided, guided-nee, light, light-guided, bdpt, bdpt-guided)")
    })
}

pub(super) fn parse_learning_rate(s: &str) -> Result<LearningRate, String> {
    let number = |v: &str| v.parse::<f32>().map_err(|e| format!("`{v}`: {e}"));
    match s.split_once(':') {
        None if s == "simple" => Ok(LearningRate::SimpleAverage),
        None if s == "region" => Ok(LearningRate::RegionVisits),
        Some(("exponential", alpha)) => Ok(LearningRate::Exponential { alpha: number(alpha)? }),
        Some(("global", exponent)) => Ok(LearningRate::Global { exponent: number(exponent)? }),
        _ => Err(format!("unknown learning rate `{s}` (simple, region, exponential:ALPHA, global:EXPONENT)")),
    }
}

pub(super) fn parse_integral(s: &str) -> Result<IntegralEstimator, String> {
    match s {
        "weighted" => Ok(IntegralEstimator::BsdfWeightedSum),
        "stratified" => Ok(IntegralEstimator::StratifiedPatches),
        "max" => Ok(IntegralEstimator::MaxEntry),
        "sampled" => Ok(IntegralEstimator::BsdfSampled),
        "path" => Ok(IntegralEstimator::PathContinuation),
        _ => Err(format!("unknown integral estimator `{s}` (weighted, stratified, max, sampled, path)")),
    }
}

pub(super) fn parse_switch(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("`{s}` is neither on nor off")),
    }
}

pub(super) fn parse_patches(s: &str) -> Result<[u32; 2], String> {
    let (u, v) = s.split_once('x').ok_or_else(|| format!("`{s}` is not U×V like 8x16"))?;
    let parse = |t: &str| t.parse::<u32>().map_err(|e| format!("`{t}`: {e}"));
    Ok([parse(u)?, parse(v)?])
}

pub(super) fn parse_mapping(s: &str) -> Result<HemisphereMapping, String> {
    match s {
        "cylindrical" => Ok(HemisphereMapping::Cylindrical),
        "concentric" => Ok(HemisphereMapping::ConcentricSquare),
        _ => Err(format!("unknown mapping `{s}` (cylindrical, concentric)")),
    }
}

/// A finite number ≥ 0.
fn parse_non_negative(text: &str) -> Result<f32, String> {
    let value: f32 = text.parse().map_err(|_| format!("`{text}` is not a number"))?;
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(format!("{value} is not a finite number ≥ 0"))
    }
}

/// A finite number (NaN and infinities are refused).
fn parse_finite(text: &str) -> Result<f32, String> {
    let value: f32 = text.parse().map_err(|_| format!("`{text}` is not a number"))?;
    value.is_finite().then_some(value).ok_or_else(|| format!("{value} is not finite"))
}

/// A share in (0, 1].
fn parse_share(text: &str) -> Result<f64, String> {
    let share: f64 = text.parse().map_err(|_| format!("`{text}` is not a number"))?;
    if share > 0.0 && share <= 1.0 {
        Ok(share)
    } else {
        Err(format!("{share} is not in (0, 1]"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolutions_are_two_sides_within_the_largest_image() {
        assert_eq!(parse_resolution("320x180"), Ok([320, 180]));
        let limit = crate::scene::MAX_IMAGE_SIDE;
        for bad in ["0x10", "10x0", "10", "x10", "tenxten", "-1x5"] {
            assert!(parse_resolution(bad).is_err(), "{bad} was accepted");
        }
        assert!(parse_resolution(&format!("{}x1", limit + 1)).unwrap_err().contains(&limit.to_string()));
    }

    #[test]
    fn guide_choices_name_a_structure_auto_or_none() {
        assert_eq!(parse_guide_choice("auto").unwrap().structure(), Some(GuideStructure::Hemisphere));
        assert_eq!(parse_guide_choice("none"), Ok(GuideChoice::Off));
        assert_eq!(parse_guide_choice("tree"), Ok(GuideChoice::Structure(GuideStructure::Tree)));
        assert!(parse_guide_choice("octopus").is_err());
    }
}

/// `--roulette`: how camera paths of the guided methods end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RouletteKind {
    /// By throughput, past `--rr-depth`.
    Throughput,
    /// By the learned worth of going on against its cost (efficiency-aware).
    Efficiency,
}

fn parse_roulette_kind(name: &str) -> Result<RouletteKind, String> {
    match name {
        "throughput" => Ok(RouletteKind::Throughput),
        "efficiency" => Ok(RouletteKind::Efficiency),
        _ => Err(format!("unknown roulette `{name}` (throughput, efficiency)")),
    }
}
