//! The `lodestar` command line: parsing and the `render` and `reference` commands.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::scene_intersector::{IntersectorChoice, SceneIntersector};
use clap::{Args, Parser, Subcommand};
use guiding_core::environment::EnvironmentTiles;
use guiding_core::volume::SphereLayout;
use guiding_core::{
    EnvTileGuide, EnvTileGuideSettings, FocalGuide, FocalGuideSettings, GaussianMixtureSettings, HemisphereGrid,
    HemisphereGridSettings, HemisphereMapping, IntegralEstimator, IrradianceVolumeSettings, LearningRate, LightGuide,
    LightGuideSettings, LightUpdateRule, NextEventGate, NextEventGateSettings, PatchLayout,
    SpatialDirectionalTreeSettings, StrategyShares, UpdateRule,
};
use indicatif::{ProgressBar, ProgressStyle};

use crate::directional_guide::{DirectionalGuide, DirectionalGuideSettings, GuideStructure};
use crate::film::Combine;
use crate::integrator::{EnvironmentSampling, IntegratorSettings, LightSelection, Method};
use crate::lights::MAX_LIGHT_SPLIT;
use crate::metrics::{image_error, ImageError};
use crate::output::{read_image, write_exr, write_pfm, write_png, Image};
use crate::peer::{run_peer, Peer, PeerSettings};
use crate::plan::{auto_light_split, GuidePlan};
use crate::render::{render, Budget, Learners, Progress, RenderSettings, RenderStatistics};
use crate::scene::Scene;
use crate::schedule::Schedule;

/// Lodestar: path guiding by reinforcement learning.
#[derive(Debug, Parser)]
#[command(name = "lodestar", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render a scene; writes IMAGE.exr, IMAGE.png and IMAGE.json (and IMAGE.csv and
    /// IMAGE.svg with error against time when given a reference).
    Render(RenderArgs),
    /// Render a converged reference image (with `nee` unless told otherwise).
    Reference(ReferenceArgs),
    /// Run several methods on one scene for the same wall time each; writes
    /// DIR/compare.csv, DIR/compare.md, DIR/error.svg and every method's image.
    Compare(CompareArgs),
    /// Read a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene and write it in the project's
    /// JSON format (file names made relative to the output's folder).
    Convert(ConvertArgs),
}

#[derive(Debug, Args)]
struct ConvertArgs {
    /// The scene to read (.pbrt or .xml).
    input: PathBuf,
    /// The JSON scene to write.
    output: PathBuf,
}

fn run_convert(args: &ConvertArgs) -> Result<(), String> {
    let warnings = crate::import::convert(&args.input, &args.output).map_err(|e| e.to_string())?;
    for warning in &warnings {
        eprintln!("warning: {warning}");
    }
    eprintln!("wrote {}", args.output.display());
    Ok(())
}

#[derive(Debug, Args)]
struct CompareArgs {
    /// The scene file: scene.json, or a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene.
    scene: PathBuf,
    /// Comma-separated methods, e.g. pt,nee,guided,guided-nee; a method may name its
    /// light selection, e.g. nee:uniform,nee:power,nee:learned (else --light-selection),
    /// its environment sampling, e.g. nee+luminance,nee+tiles (else --env-sampling), and
    /// its guide structure, e.g. guided-nee@mixture (else every one --guide lists), and
    /// the GPU tracer before it, e.g. gpu:nee (the `gpu` feature).
    #[arg(long, value_delimiter = ',', value_parser = parse_compared_method, required = true)]
    methods: Vec<ComparedMethod>,
    /// Wall-clock seconds per method.
    #[arg(long)]
    seconds: f64,
    /// Reference image (.exr/.pfm/.hdr).
    #[arg(long)]
    reference: PathBuf,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Times (seconds) at which the table reports relMSE; default 10 and --seconds.
    #[arg(long, value_delimiter = ',')]
    report_at: Vec<f64>,
    /// A peer renderer run first, for --seconds, as one more row: mitsuba (Mitsuba 3's
    /// vectorised path tracer, installed by scripts/peer-mitsuba.sh into .cache on first
    /// use; a scene it cannot render alike is refused with the feature named). It gets
    /// --max-depth, --rr-depth, --resolution and --threads.
    #[arg(long, value_parser = Peer::from_name)]
    peer: Option<Peer>,
    #[command(flatten)]
    options: TraceOptions,
}

#[derive(Debug, Args)]
struct RenderArgs {
    /// The scene file: scene.json, or a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene.
    scene: PathBuf,
    /// pt, nee, guided or guided-nee. Default guided-nee: at 60 s, with the guided
    /// defaults, its relMSE ÷ nee's was 0.423 and 0.428 on door 160×120 (seeds 41, 42),
    /// 0.743 and 0.917 on cornell 128²; six scenes in the README.
    #[arg(long, default_value = "guided-nee", value_parser = parse_method)]
    integrator: Method,
    #[command(flatten)]
    options: TraceOptions,
    /// Samples per pixel (default 64 unless --seconds is given).
    #[arg(long, conflicts_with = "seconds")]
    spp: Option<u32>,
    /// Wall-clock seconds of rendering.
    #[arg(long)]
    seconds: Option<f64>,
    /// Output image (.exr); .png and .json are written beside it.
    #[arg(long)]
    out: PathBuf,
    /// Also write IMAGE.pfm.
    #[arg(long)]
    pfm: bool,
    /// Reference image (.exr/.pfm/.hdr) for error against time (IMAGE.csv).
    #[arg(long)]
    reference: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct ReferenceArgs {
    /// The scene file: scene.json, or a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene.
    scene: PathBuf,
    /// Samples per pixel.
    #[arg(long)]
    spp: u32,
    /// Any unbiased integrator; guided-nee converges fastest on hard scenes.
    #[arg(long, default_value = "nee", value_parser = parse_method)]
    integrator: Method,
    /// Light selection (learned converges fastest with many occluded lights).
    #[arg(long, default_value = "power", value_parser = LightSelection::from_name)]
    light_selection: LightSelection,
    /// Environment sampling (tiles converges fastest where most of the sky is hidden).
    #[arg(long, default_value = "luminance", value_parser = EnvironmentSampling::from_name)]
    env_sampling: EnvironmentSampling,
    /// Output image (.exr).
    #[arg(long)]
    out: PathBuf,
    /// Also write REF.pfm.
    #[arg(long)]
    pfm: bool,
    /// Random seed.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Image size W×H instead of the scene's (same vertical field of view).
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<[u32; 2]>,
}

/// `--resolution`: W×H within the largest image side.
fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let [width, height] = parse_patches(s)?;
    let limit = crate::scene::MAX_IMAGE_SIDE;
    if width == 0 || height == 0 || width > limit || height > limit {
        return Err(format!("`{s}`: each side must be in 1..={limit}"));
    }
    Ok([width, height])
}

/// Renders `prepared` at `resolution` when one is given.
fn resize(prepared: &mut Prepared, resolution: Option<[u32; 2]>) {
    if let Some([width, height]) = resolution {
        prepared.scene.camera = prepared.scene.camera.with_resolution(width, height);
    }
}

/// The learned guide share's default cost of guiding (`--guide-share-cost`).
pub const GUIDE_SHARE_COST: f32 = 0.3;

/// Options shared by every command that traces paths.
#[derive(Debug, Args, Clone)]
pub struct TraceOptions {
    /// The directional guide of the guided methods: auto (a hemisphere grid unless every
    /// surface is a mirror or glass; see the printed plan), hemisphere (probes with
    /// hemispheres of patches), volume (full-sphere tables in an adaptive octree),
    /// mixture (grid cells with vMF mixtures), or none. compare
    /// takes several, comma-separated, and runs each guided method with each.
    #[arg(long, default_value = "auto", value_delimiter = ',', value_parser = parse_guide_choice)]
    guide: Vec<GuideChoice>,
    /// Lobes per mixture (--guide mixture), 1..=8. 2 measured best on door and cornell
    /// (against 3 and 6, 15 s each: fewer lobes cost less per sample).
    #[arg(long, default_value_t = 2)]
    mixture_lobes: usize,
    /// Image size W×H instead of the scene's (same vertical field of view), e.g. 320x180.
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<[u32; 2]>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Most scattering vertices per path.
    #[arg(long, default_value_t = 32)]
    max_depth: u32,
    /// Russian roulette after this many vertices.
    #[arg(long, default_value_t = 4)]
    rr_depth: u32,
    /// Probability of sampling the guide instead of the BSDF, in [0, 1]: with the learned
    /// share (the CPU's default) the most any region takes. Default 0.5 on the CPU: against
    /// 0.3, guided-nee relMSE × spp at 30 s, seeds 41 and 42, cornell 128² 0.154/0.153
    /// against 0.167/0.162, door 160×120 11.77/11.18 against 11.44/11.17, glossy 128²
    /// 17.63/16.90 against 17.93/16.98; Veach Ajar relMSE at 60 s 3.61/3.18 against
    /// 3.43/3.26. 0.3 on the GPU, whose share is fixed at every vertex (0.5 compounds
    /// larger mixture weights over bounces).
    #[arg(long)]
    p_guide: Option<f32>,
    /// Only the first N vertices of each path use the guide; deeper ones sample the BSDF
    /// alone, at nee's cost per vertex. Default 1 on the CPU, measured best: guided-nee ÷
    /// nee at 20 s on cornell 128² 1.01–1.09 (every vertex: 1.29), on door 160×120 1.21
    /// (every vertex: 1.45; 2: 1.16). The GPU tracer guides every vertex.
    #[arg(long)]
    guide_depth: Option<u32>,
    /// Most probability of aiming at the focal guide (points in space where light squeezes
    /// through, learned from the segments that carried it) instead of the BSDF, at every
    /// vertex of a guided method; each region of space learns its own share up to it (the
    /// least variance among 0, 0.02, … 0.5, --focal-share-cost); p_guide + p_focal ≤ 1. 0 leaves it out.
    /// Default 0.5 (at most 1 − p_guide) on the CPU, 0 on the GPU (which has no focal
    /// guide). 0.5 with `--guide none --p-guide 0 --schedule iterative`, at 60 s: door
    /// 160×120 0.57–0.60 × nee's relMSE, cornell 128² 1.02 ×.
    #[arg(long)]
    p_focal: Option<f32>,
    /// The focal guide's most boxes (its densest leaves), 1..=1024.
    #[arg(long)]
    focal_boxes: Option<u32>,
    /// The focal guide's density ratio: a leaf is sampled when its density is at least
    /// this many times the occupied mean.
    #[arg(long)]
    focal_ratio: Option<f32>,
    /// The focal guide's split share: a leaf holding more of the mass splits.
    #[arg(long)]
    focal_split: Option<f32>,
    /// The focal guide's merge ratio: neighbouring focal leaves whose densities differ by
    /// at most this factor become one box; 0 keeps every leaf its own box.
    #[arg(long)]
    focal_merge: Option<f32>,
    /// Points along each recorded segment where the focal guide deposits its mass, 1..=64,
    /// or 0: exactly, into every octree leaf the segment crosses by the length inside.
    /// Default 4: exact deposits measured no better on door 160×120 (30 s, seed 41, relMSE ×
    /// spp 12.3 against 11.9), the octree's leaves staying about as coarse (7–14 cm around
    /// a 1 cm gap) either way.
    #[arg(long)]
    focal_deposits: Option<u32>,
    /// Share of paths the focal guide learns from, in (0, 1]. 0.25 measured best (60 s,
    /// against 1: cornell 128² ÷ nee 1.02 against 1.06–1.20, its paths/s 0.98 × nee's
    /// against 0.81–0.92; door 160×120 0.60 against 0.57).
    #[arg(long, default_value_t = 0.25)]
    focal_learn: f32,
    /// The directional guide's share of the scattering: fixed (--p-guide at every guided
    /// vertex) or learned (each cell of the focal guide's selection grid picks, up to
    /// --p-guide, the share whose estimator had the least variance times its cost
    /// (--guide-share-cost), as the focal guide does; where it picks 0 the guide is not even located). Default learned on
    /// the CPU, fixed on the GPU (which learns no share). With `--guide hemisphere
    /// --schedule iterative --p-guide 0.3 --p-focal 0.5`, 60 s, ÷ nee (seeds 21, 22):
    /// door 160×120 0.494 and 0.486, cornell 128² 0.966 and 1.218 (per sample 0.80 both
    /// times; its paths/s 0.83 and 0.66 of nee's).
    #[arg(long, value_parser = GuideShare::from_name)]
    guide_share: Option<GuideShare>,
    /// The focal guide's selection cells along the scene's longest side, 1..=64: each
    /// learns its own probability of aiming at the boxes.
    #[arg(long)]
    focal_cells: Option<u32>,
    /// The learned guide share's cost of guiding, ≥ 0: a cell gives the directional guide a
    /// share above 0 only where the variance it leaves, times 1 + this, is below the
    /// variance at 0 (the guide's lookups cost time at every vertex of the cell). 0.3
    /// measured best: against 0, guided-nee at 30 s, relMSE ÷ (seeds 41 and 42), door
    /// 160×120 0.94/0.96 (the focal guide serves it: the guide kept 1 of 96 cells, per
    /// sample equal), glossy 128² 0.97/0.95, many_lights 160×120 0.97/0.98, cornell 128²
    /// 1.01/1.04 (per sample 1.01/1.00); 1 lost 19 % per sample on cornell.
    #[arg(long, default_value_t = GUIDE_SHARE_COST)]
    guide_share_cost: f32,
    /// The focal guide's selection cost, ≥ 0, as --guide-share-cost for aiming at the
    /// boxes. Default 0: at 0.1 or 0.3 for both, door 160×120 lost 12 % and 87 % per sample
    /// (30 s, seed 41): where both strategies serve a cell each one's own gain looks small
    /// and both were dropped.
    #[arg(long)]
    focal_share_cost: Option<f32>,
    /// Learning rate: simple (α = 1/(1+visits)), region, exponential:ALPHA or global:EXPONENT.
    #[arg(long, default_value = "simple", value_parser = parse_learning_rate)]
    learning_rate: LearningRate,
    /// Integral of Eq. (1): sampled (the weighted sum for diffuse surfaces, one BSDF
    /// sample for glossy ones: on Veach Ajar 3× the paths/s of weighted, and a 4.7× lower
    /// relMSE at 30 s), weighted (BSDF-weighted sum over every patch), stratified, max, or
    /// path (the path's own continuation, no lookup). Default: path for the tree,
    /// sampled for the others.
    #[arg(long, value_parser = parse_integral)]
    integral: Option<IntegralEstimator>,
    /// When guided methods learn: online (every pass, every pass kept) or iterative
    /// (training iterations of 1, 2, 4, … passes with a refit after each, then a frozen
    /// final image; --combine says how the iterations make the image). Default
    /// iterative on the CPU, online on the GPU (which learns online only).
    #[arg(long, value_parser = Schedule::from_name)]
    schedule: Option<Schedule>,
    /// How the iterative schedule's iterations make the image: final (the frozen last
    /// one alone), samples (every pass alike, unbiased) or inverse-variance (each
    /// iteration by the inverse of its estimated relative variance, estimated at each
    /// pixel without it, and no sample above one of the latest iteration). Door 160×120,
    /// 30 s, focal guided-nee, relMSE × spp, seeds 11 and 12: samples 12.82 and 12.60,
    /// inverse-variance 12.83 and 12.26, final 10.98 and 10.97 (of fewer samples: relMSE
    /// 1.5 times); cornell 128²: 0.194/0.198 against 0.195/0.200. Samples stays.
    #[arg(long, default_value = Combine::default().name(), value_parser = Combine::from_name)]
    combine: Combine,
    /// The tree guide's memory budget, MiB.
    #[arg(long, default_value_t = 16.0)]
    tree_mib: f64,
    /// The tree's spatial split constant c: a leaf splits past c·√R of an epoch's R records.
    #[arg(long)]
    tree_threshold: Option<f32>,
    /// The tree's directional split share ρ of a leaf's flux, in (0, 1).
    #[arg(long)]
    tree_flux_fraction: Option<f32>,
    /// Whether the tree's distributions fold onto the normal's hemisphere (on, off).
    #[arg(long, value_parser = parse_switch)]
    tree_fold: Option<bool>,
    /// Patches per hemisphere as U×V, e.g. 8x16 (for --guide volume: bands of cos θ ×
    /// sectors of φ over the whole sphere).
    #[arg(long, default_value = "8x16", value_parser = parse_patches)]
    patches: [u32; 2],
    /// cylindrical or concentric.
    #[arg(long, default_value = "cylindrical", value_parser = parse_mapping)]
    mapping: HemisphereMapping,
    /// Guide memory budget, MiB. 0.5 measured best on door (the tables stay in the L2
    /// cache) and equal on cornell; guiding-core's own default is 2.
    #[arg(long, default_value_t = 0.5)]
    guide_mib: f64,
    /// Q of every patch before learning (radiance).
    #[arg(long)]
    initial_q: Option<f32>,
    /// Share of each probe's sampling probability spread uniformly, in [0, 1].
    #[arg(long)]
    uniform_mix: Option<f32>,
    /// Largest angle between a hit's normal and its probe's, degrees.
    #[arg(long)]
    max_normal_angle: Option<f32>,
    /// Exponent γ of the sampling weights Q^γ, in (0, 1].
    #[arg(long)]
    sampling_exponent: Option<f32>,
    /// Whether a probe samples its patches by Q·∫cos (the product with a Lambertian
    /// surface's cosine) rather than by Q alone (on, off). Default on for the CPU: with
    /// `--guide hemisphere --guide-share learned --schedule iterative --p-guide 0.3
    /// --p-focal 0.5`, 30 s, relMSE × spp off → on, seeds 31 and 32: cornell 128² 0.160 →
    /// 0.149 and 0.162 → 0.149, door 160×120 15.67 → 14.92 and 13.99 → 13.79. The GPU
    /// tracer samples by Q alone.
    #[arg(long, value_parser = parse_switch)]
    cosine_product: Option<bool>,
    /// Guided methods: seconds of training passes whose samples are discarded (their
    /// time counts towards --seconds).
    #[arg(long, default_value_t = 0.0)]
    train_seconds: f64,
    /// Ray tracing library: auto (Embree where this lodestar was built with the `embree`
    /// feature, as scripts/render.sh builds it, else obvhs), obvhs (CWBVH), obvhs-bvh2, or
    /// embree. Embree measured 1.16–1.22× obvhs's nee paths/s (cornell 128², door 160×120,
    /// 20 s) and 1.30–1.34× its guided-nee paths/s.
    #[arg(long, default_value = "auto", value_parser = IntersectorChoice::from_name)]
    intersector: IntersectorChoice,
    /// Where paths are traced: cpu (all cores), or gpu (a wgpu compute shader on a
    /// Vulkan adapter; needs the `gpu` feature). compare takes gpu:METHOD instead.
    #[arg(long, default_value = "cpu", value_parser = Device::from_name)]
    device: Device,
    /// Next-event light selection: auto (learned with many lights, else power; see the
    /// printed plan), uniform, power, or learned (Eq. 3, per grid cell).
    #[arg(long, default_value = "auto", value_parser = parse_light_selection)]
    light_selection: Auto<LightSelection>,
    /// Learned selection's rule: mean (occluded rays count as zero), unoccluded (the seed's
    /// Eq. 3: only arriving rays), or visibility (arrived / shot, times power).
    #[arg(long, default_value = "mean", value_parser = parse_light_rule)]
    light_rule: LightUpdateRule,
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
    nee_gate: f32,
    /// The next-event gate's least probability of a shadow ray (FLOOR above), in (0, 1]. 0.03 against
    /// 0.1 on door (30 s, seeds 11 and 12): relMSE 0.89 and 1.04 times, so 0.1 stays.
    #[arg(long, default_value_t = 0.1)]
    nee_gate_floor: f32,
    /// Learned selection's memory budget, MiB.
    #[arg(long, default_value_t = 1.0)]
    light_guide_mib: f64,
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
    light_split: Auto<u32>,
    /// Next-event environment sampling: auto (tiles when there is an environment; see the
    /// printed plan), luminance (plain importance sampling), or tiles (learned per cell).
    #[arg(long, default_value = "auto", value_parser = parse_environment_sampling)]
    env_sampling: Auto<EnvironmentSampling>,
    /// Environment tiles across × down the lat-long map. 32x16 measured best on window
    /// (against 8x4, 16x8 and 64x32; 2 seeds × 15 s).
    #[arg(long, default_value = "32x16", value_parser = parse_patches)]
    env_tiles: [u32; 2],
    /// Share of each cell's tile probability kept in proportion to power, in [0, 1).
    /// 0.1 measured best on window (against 0.2 and 0.4).
    #[arg(long, default_value_t = 0.1)]
    env_power_mix: f32,
    /// Environment-tile guide's memory budget for its per-cell tables, MiB.
    #[arg(long, default_value_t = 1.0)]
    env_guide_mib: f64,
}

/// A choice given on the command line, or `None` for `auto` (the plan decides). A
/// newtype, as clap reads a bare `Option` field as "may be absent".
#[derive(Clone, Copy, Debug)]
struct Auto<T>(Option<T>);

impl<T> Auto<T> {
    fn parse(s: &str, parse: impl Fn(&str) -> Result<T, String>) -> Result<Self, String> {
        if s == "auto" {
            Ok(Auto(None))
        } else {
            parse(s).map(|choice| Auto(Some(choice)))
        }
    }
}

fn parse_environment_sampling(s: &str) -> Result<Auto<EnvironmentSampling>, String> {
    Auto::parse(s, EnvironmentSampling::from_name)
}

fn parse_light_selection(s: &str) -> Result<Auto<LightSelection>, String> {
    Auto::parse(s, LightSelection::from_name)
}

fn parse_light_split(s: &str) -> Result<Auto<u32>, String> {
    Auto::parse(s, |s| match s.parse::<u32>() {
        Ok(n) if (1..=MAX_LIGHT_SPLIT).contains(&n) => Ok(n),
        _ => Err(format!("--light-split `{s}` must be auto or a whole number in 1..={MAX_LIGHT_SPLIT}")),
    })
}

/// `--guide`: a structure, `auto` (the default structure) or `none`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GuideChoice {
    Auto,
    Structure(GuideStructure),
    Off,
}

impl GuideChoice {
    /// The structure to build, if any: `auto` is the hemisphere grid.
    fn structure(self) -> Option<GuideStructure> {
        match self {
            GuideChoice::Auto => Some(GuideStructure::Hemisphere),
            GuideChoice::Structure(structure) => Some(structure),
            GuideChoice::Off => None,
        }
    }
}

fn parse_guide_choice(s: &str) -> Result<GuideChoice, String> {
    match s {
        "auto" => Ok(GuideChoice::Auto),
        "none" => Ok(GuideChoice::Off),
        _ => GuideStructure::from_name(s).map(GuideChoice::Structure),
    }
}

/// One method of `compare`: METHOD[:LIGHT_SELECTION][+ENVIRONMENT_SAMPLING][@GUIDE].
#[derive(Clone, Copy, Debug)]
struct ComparedMethod {
    /// Where it traces (`gpu:` before the method).
    device: Device,
    method: Method,
    selection: Option<LightSelection>,
    environment: Option<EnvironmentSampling>,
    guide: Option<GuideStructure>,
}

impl ComparedMethod {
    /// The name it was given (and its output files take).
    fn name(&self) -> String {
        let selection = self.selection.map(|s| format!(":{}", s.name())).unwrap_or_default();
        let environment = self.environment.map(|e| format!("+{}", e.name())).unwrap_or_default();
        let guide = self.guide.map(|g| format!("@{}", g.name())).unwrap_or_default();
        let device = if self.device == Device::Gpu { "gpu:" } else { "" };
        format!("{device}{}{selection}{environment}{guide}", self.method.name())
    }
}

fn parse_compared_method(s: &str) -> Result<ComparedMethod, String> {
    let (device, s) = match s.strip_prefix("gpu:") {
        Some(rest) => (Device::Gpu, rest),
        None => (Device::Cpu, s),
    };
    let (s, guide) = match s.split_once('@') {
        Some((rest, guide)) => (rest, Some(GuideStructure::from_name(guide)?)),
        None => (s, None),
    };
    let (rest, environment) = match s.split_once('+') {
        Some((rest, environment)) => (rest, Some(EnvironmentSampling::from_name(environment)?)),
        None => (s, None),
    };
    let (method, selection) = match rest.split_once(':') {
        Some((method, selection)) => (parse_method(method)?, Some(LightSelection::from_name(selection)?)),
        None => (parse_method(rest)?, None),
    };
    Ok(ComparedMethod { device, method, selection, environment, guide })
}

fn parse_light_rule(s: &str) -> Result<LightUpdateRule, String> {
    match s {
        "mean" => Ok(LightUpdateRule::MeanContribution),
        "unoccluded" => Ok(LightUpdateRule::UnoccludedAverage),
        "visibility" => Ok(LightUpdateRule::VisibilityRatio),
        _ => Err(format!("unknown light rule `{s}` (mean, unoccluded, visibility)")),
    }
}

fn parse_method(s: &str) -> Result<Method, String> {
    Method::from_name(s).ok_or_else(|| format!("unknown integrator `{s}` (pt, nee, guided, guided-nee)"))
}

fn parse_learning_rate(s: &str) -> Result<LearningRate, String> {
    let number = |v: &str| v.parse::<f32>().map_err(|e| format!("`{v}`: {e}"));
    match s.split_once(':') {
        None if s == "simple" => Ok(LearningRate::SimpleAverage),
        None if s == "region" => Ok(LearningRate::RegionVisits),
        Some(("exponential", alpha)) => Ok(LearningRate::Exponential { alpha: number(alpha)? }),
        Some(("global", exponent)) => Ok(LearningRate::Global { exponent: number(exponent)? }),
        _ => Err(format!("unknown learning rate `{s}` (simple, region, exponential:ALPHA, global:EXPONENT)")),
    }
}

fn parse_integral(s: &str) -> Result<IntegralEstimator, String> {
    match s {
        "weighted" => Ok(IntegralEstimator::BsdfWeightedSum),
        "stratified" => Ok(IntegralEstimator::StratifiedPatches),
        "max" => Ok(IntegralEstimator::MaxEntry),
        "sampled" => Ok(IntegralEstimator::BsdfSampled),
        "path" => Ok(IntegralEstimator::PathContinuation),
        _ => Err(format!("unknown integral estimator `{s}` (weighted, stratified, max, sampled, path)")),
    }
}

fn parse_switch(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("`{s}` is neither on nor off")),
    }
}

fn parse_patches(s: &str) -> Result<[u32; 2], String> {
    let (u, v) = s.split_once('x').ok_or_else(|| format!("`{s}` is not U×V like 8x16"))?;
    let parse = |t: &str| t.parse::<u32>().map_err(|e| format!("`{t}`: {e}"));
    Ok([parse(u)?, parse(v)?])
}

fn parse_mapping(s: &str) -> Result<HemisphereMapping, String> {
    match s {
        "cylindrical" => Ok(HemisphereMapping::Cylindrical),
        "concentric" => Ok(HemisphereMapping::ConcentricSquare),
        _ => Err(format!("unknown mapping `{s}` (cylindrical, concentric)")),
    }
}

impl TraceOptions {
    /// The settings of `structure` from the options (budget, update rule and the
    /// structure's own).
    fn guide_settings(&self, structure: GuideStructure) -> Result<DirectionalGuideSettings, String> {
        let hemisphere = self.hemisphere_settings()?;
        Ok(match structure {
            GuideStructure::Hemisphere => hemisphere.into(),
            GuideStructure::Volume => {
                let defaults = IrradianceVolumeSettings::default();
                let settings = IrradianceVolumeSettings {
                    budget_bytes: hemisphere.budget_bytes,
                    layout: SphereLayout { resolution: self.patches },
                    update_rule: hemisphere.update_rule,
                    initial_q: self.initial_q.unwrap_or(defaults.initial_q),
                    uniform_mix: self.uniform_mix.unwrap_or(defaults.uniform_mix),
                    ..defaults
                };
                settings.validate().map_err(|e| format!("volume guide: {e}"))?;
                settings.into()
            }
            GuideStructure::Mixture => {
                let defaults = GaussianMixtureSettings::default();
                let settings = GaussianMixtureSettings {
                    budget_bytes: hemisphere.budget_bytes,
                    lobes: self.mixture_lobes,
                    update_rule: hemisphere.update_rule,
                    initial_q: self.initial_q.unwrap_or(defaults.initial_q),
                    uniform_mix: self.uniform_mix.unwrap_or(defaults.uniform_mix),
                    ..defaults
                };
                settings.validate().map_err(|e| format!("mixture guide: {e}"))?;
                settings.into()
            }
            GuideStructure::Tree => {
                if !(self.tree_mib.is_finite() && self.tree_mib > 0.0) {
                    return Err(format!("--tree-mib {} must be positive", self.tree_mib));
                }
                let defaults = SpatialDirectionalTreeSettings::default();
                let settings = SpatialDirectionalTreeSettings {
                    budget_bytes: (self.tree_mib * (1 << 20) as f64) as usize,
                    update_rule: UpdateRule {
                        learning_rate: self.learning_rate,
                        integral: self.integral.unwrap_or(defaults.update_rule.integral),
                    },
                    uniform_mix: self.uniform_mix.unwrap_or(defaults.uniform_mix),
                    spatial_threshold: self.tree_threshold.unwrap_or(defaults.spatial_threshold),
                    flux_fraction: self.tree_flux_fraction.unwrap_or(defaults.flux_fraction),
                    fold_to_hemisphere: self.tree_fold.unwrap_or(defaults.fold_to_hemisphere),
                    ..defaults
                };
                settings.validate().map_err(|e| format!("tree guide: {e}"))?;
                settings.into()
            }
        })
    }

    /// The one `--guide` of `render` and `reference`.
    fn single_guide(&self) -> Result<GuideChoice, String> {
        match self.guide.as_slice() {
            [choice] => Ok(*choice),
            _ => Err("--guide takes one structure here (several only with compare)".into()),
        }
    }

    /// The directional guide's most share: `--p-guide`, else 0.5 on the CPU (where each
    /// region learns its own share up to it) and 0.3 on the GPU (a fixed share).
    fn p_guide(&self) -> f32 {
        match (self.p_guide, self.device) {
            (Some(p), _) => p,
            (None, Device::Gpu) => 0.3,
            (None, _) => 0.5,
        }
    }

    /// The focal guide's most share: `--p-focal`, else 0.5 (at most 1 − p_guide) on the
    /// CPU and 0 on the GPU.
    fn p_focal(&self) -> f32 {
        match (self.p_focal, self.device) {
            (Some(p), _) => p,
            (None, Device::Gpu) => 0.0,
            (None, _) => 0.5f32.min(1.0 - self.p_guide()),
        }
    }

    /// `--guide-share`, else learned on the CPU and fixed on the GPU.
    fn guide_share(&self) -> GuideShare {
        match (self.guide_share, self.device) {
            (Some(share), _) => share,
            (None, Device::Gpu) => GuideShare::Fixed,
            (None, _) => GuideShare::Learned,
        }
    }

    /// `--schedule`, else iterative on the CPU and online on the GPU.
    fn schedule(&self) -> Schedule {
        match (self.schedule, self.device) {
            (Some(schedule), _) => schedule,
            (None, Device::Gpu) => Schedule::Online,
            (None, _) => Schedule::Iterative,
        }
    }

    fn focal_settings(&self) -> Result<FocalGuideSettings, String> {
        let p_focal = self.p_focal();
        if !(0.0..=1.0 - self.p_guide()).contains(&p_focal) {
            return Err(format!("--p-focal {p_focal} must be in [0, 1 − p_guide = {}]", 1.0 - self.p_guide()));
        }
        if !(self.focal_learn > 0.0 && self.focal_learn <= 1.0) {
            return Err(format!("--focal-learn {} must be in (0, 1]", self.focal_learn));
        }
        let defaults = FocalGuideSettings::default();
        let settings = FocalGuideSettings {
            max_boxes: self.focal_boxes.unwrap_or(defaults.max_boxes),
            focal_ratio: self.focal_ratio.unwrap_or(defaults.focal_ratio),
            split_share: self.focal_split.unwrap_or(defaults.split_share),
            share_resolution: self.focal_cells.unwrap_or(defaults.share_resolution),
            share_cost: self.focal_share_cost.unwrap_or(defaults.share_cost),
            merge_ratio: self.focal_merge.unwrap_or(defaults.merge_ratio),
            deposits_per_segment: self.focal_deposits.unwrap_or(defaults.deposits_per_segment),
            ..defaults
        };
        settings.validate().map_err(|e| format!("focal guide: {e}"))?;
        Ok(settings)
    }

    fn hemisphere_settings(&self) -> Result<HemisphereGridSettings, String> {
        if !(self.guide_mib.is_finite() && self.guide_mib > 0.0) {
            return Err(format!("--guide-mib {} must be positive", self.guide_mib));
        }
        if !(0.0..=1.0).contains(&self.p_guide()) {
            return Err(format!("--p-guide {} must be in [0, 1]", self.p_guide()));
        }
        let defaults = HemisphereGridSettings::default();
        let settings = HemisphereGridSettings {
            budget_bytes: (self.guide_mib * (1 << 20) as f64) as usize,
            layout: PatchLayout { mapping: self.mapping, resolution: self.patches },
            update_rule: UpdateRule {
                learning_rate: self.learning_rate,
                integral: self.integral.unwrap_or(IntegralEstimator::BsdfSampled),
            },
            initial_q: self.initial_q.unwrap_or(defaults.initial_q),
            uniform_mix: self.uniform_mix.unwrap_or(defaults.uniform_mix),
            max_normal_angle_deg: self.max_normal_angle.unwrap_or(defaults.max_normal_angle_deg),
            sampling_exponent: self.sampling_exponent.unwrap_or(defaults.sampling_exponent),
            cosine_product: self.cosine_product.unwrap_or(self.device == Device::Cpu),
            ..defaults
        };
        settings.validate().map_err(|e| e.to_string())?;
        Ok(settings)
    }

    fn integrator(&self, method: Method, plan: &GuidePlan) -> IntegratorSettings {
        let guide_depth = match (self.guide_depth, self.device) {
            (Some(depth), _) => depth,
            (None, Device::Gpu) => u32::MAX,
            (None, _) => 1,
        };
        IntegratorSettings {
            method,
            max_depth: self.max_depth.max(1),
            rr_depth: self.rr_depth,
            guide_probability: self.p_guide(),
            guide_depth,
            focal_probability: self.p_focal(),
            focal_learning_share: self.focal_learn,
            learned_guide_share: self.guide_share() == GuideShare::Learned,
            density_weighted_learning: true,
            nee_weighs_guide: false,
            learn: true,
            light_selection: plan.light_selection,
            environment_sampling: plan.environment_sampling,
        }
    }

    /// The directional guide's settings if `method` guides and `choice` is not `none`
    /// (the plan may still leave it out).
    fn directional_guide(
        &self,
        method: Method,
        choice: GuideChoice,
    ) -> Result<Option<DirectionalGuideSettings>, String> {
        match choice.structure() {
            Some(structure) if method.uses_guide() => self.guide_settings(structure).map(Some),
            _ => Ok(None),
        }
    }

    /// What to build for light selection under `method`.
    fn light_request(&self, method: Method) -> Result<LightRequest, String> {
        if !(self.light_guide_mib.is_finite() && self.light_guide_mib > 0.0) {
            return Err(format!("--light-guide-mib {} must be positive", self.light_guide_mib));
        }
        if !(self.nee_gate.is_finite() && self.nee_gate >= 0.0) {
            return Err(format!("--nee-gate {} must be finite and at least 0", self.nee_gate));
        }
        if !(self.nee_gate_floor > 0.0 && self.nee_gate_floor <= 1.0) {
            return Err(format!("--nee-gate-floor {} must be in (0, 1]", self.nee_gate_floor));
        }
        let budget_bytes = (self.light_guide_mib * (1 << 20) as f64) as usize;
        // The gate learns, so unguided methods (the baselines) and the GPU tracer (which
        // has no light guide) shoot every shadow ray.
        let gated = method.uses_guide() && self.device == Device::Cpu;
        let settings = LightGuideSettings { budget_bytes, rule: self.light_rule, ..Default::default() };
        settings.validate().map_err(|e| e.to_string())?;
        let gate = (gated && self.nee_gate > 0.0).then_some(NextEventGateSettings {
            scale: self.nee_gate,
            floor: self.nee_gate_floor,
            ..Default::default()
        });
        if !(self.env_guide_mib.is_finite() && self.env_guide_mib > 0.0) {
            return Err(format!("--env-guide-mib {} must be positive", self.env_guide_mib));
        }
        let environment_settings = EnvTileGuideSettings {
            budget_bytes: (self.env_guide_mib * (1 << 20) as f64) as usize,
            tiles: self.env_tiles,
            power_mix: self.env_power_mix,
            ..Default::default()
        };
        environment_settings.validate().map_err(|e| format!("environment guide: {e}"))?;
        // Like the gate, the parts are learned: baselines and the GPU use whole triangles.
        let split = if gated { self.light_split.0 } else { Some(1) };
        Ok(LightRequest {
            split,
            gate,
            selection: self.light_selection.0,
            settings,
            environment: self.env_sampling.0,
            environment_settings,
            next_event_estimation: method.uses_nee(),
        })
    }
}

/// Timings of the set-up stages, seconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct SetupTimes {
    /// Reading and checking the scene.
    pub load: f64,
    /// Building the BVH.
    pub bvh: f64,
    /// Placing probes and allocating the guide.
    pub guide: f64,
}

/// Where paths are traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    /// The CPU tracer on every core (rayon).
    #[default]
    Cpu,
    /// The GPU tracer (feature `gpu`).
    Gpu,
}

impl Device {
    /// Parses `cpu` or `gpu`.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "cpu" => Ok(Device::Cpu),
            "gpu" => Ok(Device::Gpu),
            _ => Err(format!("unknown device `{name}` (cpu, gpu)")),
        }
    }
}

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

/// A scene loaded with its intersector and, for guided methods, its guide.
pub struct Prepared {
    /// The scene.
    pub scene: Scene,
    /// Its intersector.
    pub intersector: SceneIntersector,
    /// The directional guide, for guided methods.
    pub guide: Option<DirectionalGuide>,
    /// The focal guide, built at the first render of a guided method that aims at it.
    pub focal_guide: Option<FocalGuide>,
    /// The directional guide's learned shares, built at the first render that learns them.
    pub guide_shares: Option<StrategyShares>,
    /// Its settings.
    pub focal_settings: FocalGuideSettings,
    /// The learned guide share's cost of guiding (`--guide-share-cost`).
    pub guide_share_cost: f32,
    /// The learned light selection, when the plan asks for it and the scene has area lights.
    pub light_guide: Option<LightGuide>,
    /// The next-event gate, for guided methods on the CPU with area lights.
    pub gate: Option<NextEventGate>,
    /// The learned environment sampling, when the plan asks for it and the scene has an
    /// environment.
    pub environment_guide: Option<EnvTileGuide>,
    /// What was built and why.
    pub plan: GuidePlan,
    /// Set-up timings.
    pub times: SetupTimes,
    /// Where [`render`](Self::render) traces paths.
    pub device: Device,
    /// The scene on the GPU, once a GPU render has uploaded it.
    #[cfg(feature = "gpu")]
    gpu: Option<crate::gpu::GpuTracer>,
}

impl Prepared {
    #[cfg(feature = "gpu")]
    fn render_on_gpu(
        &mut self,
        settings: &RenderSettings,
        on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        use crate::gpu::GpuGuide;
        let guide = self.guide.as_mut().filter(|_| settings.integrator.method.uses_guide());
        if guide.is_some() && settings.schedule != crate::schedule::Schedule::Online {
            return Err("the GPU tracer learns online only (--schedule online)".into());
        }
        if guide.is_some() && settings.integrator.guide_depth != u32::MAX {
            return Err("the GPU tracer guides every vertex (leave out --guide-depth)".into());
        }
        if settings.integrator.method.uses_guide() && settings.integrator.focal_probability > 0.0 {
            return Err("the GPU tracer has no focal guide yet (leave out --p-focal)".into());
        }
        if guide.is_some() && settings.integrator.learned_guide_share {
            return Err("the GPU tracer has no learned guide share (--guide-share fixed)".into());
        }
        if let Some(DirectionalGuide::Tree(_)) = guide.as_deref() {
            return Err("the GPU tracer has no tree guide yet (--guide hemisphere, volume or mixture)".into());
        }
        if self.gpu.is_none() {
            let context = crate::gpu::GpuContext::new()?;
            eprintln!("gpu: {}", context.describe());
            let uploaded = match guide.as_deref() {
                Some(DirectionalGuide::Hemisphere(grid)) => Some(GpuGuide::Hemisphere(grid)),
                Some(DirectionalGuide::Volume(volume)) => Some(GpuGuide::Volume(volume)),
                Some(DirectionalGuide::Mixture(mixture)) => Some(GpuGuide::Mixture(mixture)),
                Some(DirectionalGuide::Tree(_)) | None => None,
            };
            let tracer = crate::gpu::GpuTracer::new(context, &self.scene, &settings.integrator, uploaded)?;
            self.gpu = Some(tracer);
        }
        let gpu = self.gpu.as_mut().ok_or("no GPU tracer")?;
        let result = gpu.render(settings, on_pass)?;
        match guide {
            Some(DirectionalGuide::Hemisphere(grid)) => gpu.download_guide(grid)?,
            Some(DirectionalGuide::Volume(volume)) => gpu.download_volume(volume)?,
            Some(DirectionalGuide::Mixture(mixture)) => gpu.download_mixture(mixture)?,
            Some(DirectionalGuide::Tree(_)) | None => {}
        }
        Ok(result)
    }

    #[cfg(not(feature = "gpu"))]
    fn render_on_gpu(
        &mut self,
        _settings: &RenderSettings,
        _on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        Err("this lodestar was built without the GPU tracer (cargo build --release -p reference-tracer --features gpu)"
            .into())
    }

    /// Bytes of every structure `method` learns with: the directional and focal guides
    /// (guided methods), the light guide and the environment guide (as built by the plan).
    pub fn learned_bytes(&self, method: Method) -> usize {
        let directions = self.guide.as_ref().filter(|_| method.uses_guide()).map_or(0, |g| g.stats().memory_bytes)
            + self.guide_shares.as_ref().filter(|_| method.uses_guide()).map_or(0, StrategyShares::memory_bytes);
        let lights = self.light_guide.as_ref().map_or(0, LightGuide::memory_bytes)
            + self.gate.as_ref().map_or(0, NextEventGate::memory_bytes);
        let environment = self.environment_guide.as_ref().map_or(0, EnvTileGuide::memory_bytes);
        let focal = self.focal_guide.as_ref().filter(|_| method.uses_guide()).map_or(0, FocalGuide::memory_bytes);
        directions + focal + lights + environment
    }

    /// Renders with the learners built (the directional guide only for guided
    /// methods), calling `on_pass` after every pass; the guide's structure picks the
    /// tracer's instance. On the GPU the scene is uploaded at the first render.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        mut on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        if self.device == Device::Gpu {
            return self.render_on_gpu(settings, on_pass);
        }
        let guided = settings.integrator.method.uses_guide();
        if guided && settings.integrator.focal_probability > 0.0 && self.focal_guide.is_none() {
            let (low, high) = self.scene.bounds();
            let focal = FocalGuide::new(low, high, self.focal_settings).map_err(|e| e.to_string())?;
            self.focal_guide = Some(focal);
        }
        let focal = self.focal_guide.as_mut().filter(|_| guided && settings.integrator.focal_probability > 0.0);
        let learns_share = guided && settings.integrator.learned_guide_share && self.guide.is_some();
        if learns_share && self.guide_shares.is_none() {
            let (low, high) = self.scene.bounds();
            let (resolution, cost) = (self.focal_settings.share_resolution, self.guide_share_cost);
            let shares = StrategyShares::new(low, high, resolution).and_then(|s| s.with_cost(cost));
            self.guide_shares = Some(shares.map_err(|e| format!("--guide-share-cost: {e}"))?);
        }
        let guide_shares = self.guide_shares.as_mut().filter(|_| learns_share);
        let lights = self.light_guide.as_mut();
        let gate = self.gate.as_mut();
        let environment = self.environment_guide.as_mut();
        let (scene, intersector) = (&self.scene, &self.intersector);
        Ok(match self.guide.as_mut().filter(|_| guided) {
            Some(DirectionalGuide::Hemisphere(guide)) => {
                let learners =
                    Learners { directions: Some(guide.as_mut()), focal, guide_shares, lights, gate, environment };
                render(scene, intersector, learners, settings, &mut on_pass)
            }
            Some(DirectionalGuide::Volume(guide)) => {
                let learners = Learners { directions: Some(guide), focal, guide_shares, lights, gate, environment };
                render(scene, intersector, learners, settings, &mut on_pass)
            }
            Some(DirectionalGuide::Mixture(guide)) => {
                let learners = Learners { directions: Some(guide), focal, guide_shares, lights, gate, environment };
                render(scene, intersector, learners, settings, &mut on_pass)
            }
            Some(DirectionalGuide::Tree(guide)) => {
                let learners = Learners { directions: Some(guide), focal, guide_shares, lights, gate, environment };
                render(scene, intersector, learners, settings, &mut on_pass)
            }
            None => {
                let learners: Learners<'_, HemisphereGrid> =
                    Learners { directions: None, focal, guide_shares, lights, gate, environment };
                render(scene, intersector, learners, settings, &mut on_pass)
            }
        })
    }
}

/// Loads a scene, builds the BVH and (when `guide` is given) the directional guide.
pub fn prepare(
    path: &Path,
    intersector: IntersectorChoice,
    guide: Option<DirectionalGuideSettings>,
) -> Result<Prepared, String> {
    let plain = LightRequest::new(Some(LightSelection::Power), Some(EnvironmentSampling::Luminance), true);
    prepare_with_lights(path, intersector, guide, plain)
}

/// How lights and the environment are to be sampled: choices, or `None` for the plan
/// to decide.
#[derive(Clone, Copy, Debug)]
pub struct LightRequest {
    /// Segments per edge each emissive triangle is cut into; `None` lets
    /// [`auto_light_split`] decide from the scene.
    pub split: Option<u32>,
    /// The selection asked for; `None` lets the [`GuidePlan`] decide.
    pub selection: Option<LightSelection>,
    /// The light guide's settings, if one is built.
    pub settings: LightGuideSettings,
    /// The next-event gate's settings, where one is to be built.
    pub gate: Option<NextEventGateSettings>,
    /// The environment sampling asked for; `None` lets the [`GuidePlan`] decide.
    pub environment: Option<EnvironmentSampling>,
    /// The environment-tile guide's settings, if one is built.
    pub environment_settings: EnvTileGuideSettings,
    /// Whether the method samples lights at all (no light guide otherwise).
    pub next_event_estimation: bool,
}

impl LightRequest {
    /// `selection` and `environment` asked for (or `None`: planned), default settings.
    pub fn new(
        selection: Option<LightSelection>,
        environment: Option<EnvironmentSampling>,
        next_event_estimation: bool,
    ) -> Self {
        Self {
            split: Some(1),
            selection,
            settings: LightGuideSettings::default(),
            gate: None,
            environment,
            environment_settings: EnvTileGuideSettings::default(),
            next_event_estimation,
        }
    }
}

/// [`prepare`], with light and environment sampling planned from the scene: a light
/// guide over the scene's bounds is built when the plan selects lights as learned, an
/// environment-tile guide when it samples the environment by tiles.
pub fn prepare_with_lights(
    path: &Path,
    intersector: IntersectorChoice,
    guide: Option<DirectionalGuideSettings>,
    lights: LightRequest,
) -> Result<Prepared, String> {
    let start = Instant::now();
    let mut scene = Scene::load(path).map_err(|e| e.to_string())?;
    if lights.next_event_estimation {
        let split = lights.split.unwrap_or_else(|| auto_light_split(scene.lights.len()));
        if split > 1 {
            scene.split_lights(split);
        }
    }
    let load = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let intersector = SceneIntersector::build(&scene.triangles, intersector)?;
    let bvh_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let mut plan =
        GuidePlan::new(&scene, guide.is_some(), lights.next_event_estimation, lights.selection, lights.environment);
    let guide = match guide {
        Some(settings) if plan.directions => {
            let guide = DirectionalGuide::build(&scene, settings)?;
            plan.note(guide.describe());
            Some(guide)
        }
        _ => None,
    };
    let (low, high) = scene.bounds();
    let light_guide = match lights.settings {
        settings
            if plan.light_selection == LightSelection::Learned
                && lights.next_event_estimation
                && !scene.lights.is_empty() =>
        {
            let light_guide = LightGuide::new(low, high, &scene.lights.powers(), settings)
                .map_err(|e| format!("light guide: {e}"))?;
            let [x, y, z] = light_guide.resolution();
            plan.note(format!(
                "light guide: {x}×{y}×{z} cells × {} lights, {} KiB",
                light_guide.light_count(),
                light_guide.memory_bytes() >> 10
            ));
            Some(light_guide)
        }
        _ => None,
    };
    let gate = match lights.gate {
        Some(settings) if lights.next_event_estimation && !scene.lights.is_empty() => {
            let gate = NextEventGate::new(low, high, settings).map_err(|e| format!("next-event gate: {e}"))?;
            let [x, y, z] = gate.resolution();
            plan.note(format!(
                "next-event gate ×{}: {x}×{y}×{z} cells, {} KiB",
                settings.scale,
                gate.memory_bytes() >> 10
            ));
            Some(gate)
        }
        _ => None,
    };
    let environment_guide = match &scene.environment {
        Some(environment)
            if plan.environment_sampling == EnvironmentSampling::Tiles && lights.next_event_estimation =>
        {
            let settings = lights.environment_settings;
            let (width, height, luminance) = environment.sky.luminance_grid();
            let tiles = EnvironmentTiles::new(width, height, &luminance, settings.tiles)
                .map_err(|e| format!("environment tiles: {e}"))?;
            let sun = environment.sun.map(|sun| sun.disk);
            let environment_guide =
                EnvTileGuide::new(low, high, tiles, sun, settings).map_err(|e| format!("environment guide: {e}"))?;
            let [x, y, z] = environment_guide.resolution();
            let [u, v] = environment_guide.tiles().tiles();
            plan.note(format!(
                "environment guide: {x}×{y}×{z} cells × {u}×{v} tiles{}, {} KiB tables + {} KiB texel CDFs",
                if environment_guide.sun().is_some() { " + sun" } else { "" },
                environment_guide.table_bytes() >> 10,
                environment_guide.tiles().memory_bytes() >> 10
            ));
            Some(environment_guide)
        }
        _ => None,
    };
    let times = SetupTimes { load, bvh: bvh_seconds, guide: start.elapsed().as_secs_f64() };
    Ok(Prepared {
        scene,
        intersector,
        guide,
        light_guide,
        gate,
        environment_guide,
        focal_guide: None,
        guide_shares: None,
        focal_settings: FocalGuideSettings::default(),
        guide_share_cost: GUIDE_SHARE_COST,
        plan,
        times,
        device: Device::Cpu,
        #[cfg(feature = "gpu")]
        gpu: None,
    })
}

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, String> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err("--threads must be at least 1".into());
        }
        builder = builder.num_threads(n);
    }
    builder.build().map_err(|e| format!("cannot start worker threads: {e}"))
}

fn progress_bar(budget: Budget) -> ProgressBar {
    let (length, template) = match budget {
        Budget::SamplesPerPixel(spp) => (spp as u64, "{bar:40} {pos}/{len} spp  {elapsed_precise} ETA {eta}"),
        Budget::Seconds(s) => ((s * 1000.0) as u64, "{bar:40} {msg}  {elapsed_precise} ETA {eta}"),
    };
    let bar = ProgressBar::new(length);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}

/// One point of an error-against-time curve.
#[derive(Clone, Copy, Debug)]
pub struct Checkpoint {
    /// Seconds of rendering.
    pub seconds: f64,
    /// Samples per pixel reached.
    pub spp: u32,
    /// Path counters at that time.
    pub counters: crate::integrator::PathCounters,
    /// Error against the reference.
    pub error: ImageError,
}

/// Renders a prepared scene, recording the error against `reference` after passes
/// 1, 2, 4, 8, …, after the first pass to end at or past each of `report_times`
/// (seconds), and after the last.
pub fn render_prepared(
    prepared: &mut Prepared,
    settings: &RenderSettings,
    reference: Option<&Image>,
    report_times: &[f64],
    show_progress: bool,
) -> Result<(Image, RenderStatistics, Vec<Checkpoint>), String> {
    let bar = if show_progress { progress_bar(settings.budget) } else { ProgressBar::hidden() };
    let mut checkpoints = Vec::new();
    let mut previous_seconds = 0.0;
    let (image, statistics) = prepared.render(settings, |progress| {
        match settings.budget {
            Budget::SamplesPerPixel(_) => bar.set_position(progress.passes as u64),
            Budget::Seconds(_) => {
                bar.set_position((progress.seconds * 1000.0) as u64);
                bar.set_message(format!("{} spp", progress.passes));
            }
        }
        let crossed = report_times.iter().any(|&t| previous_seconds < t && progress.seconds >= t);
        previous_seconds = progress.seconds;
        if let Some(reference) = reference {
            if progress.passes.is_power_of_two() || crossed {
                if let Some(error) = image_error(&progress.image(), reference) {
                    checkpoints.push(Checkpoint {
                        seconds: progress.seconds,
                        spp: progress.passes,
                        counters: progress.counters,
                        error,
                    });
                }
            }
        }
    })?;
    bar.finish_and_clear();
    if let Some(reference) = reference {
        if checkpoints.last().is_none_or(|c| c.spp != statistics.passes) {
            if let Some(error) = image_error(&image, reference) {
                checkpoints.push(Checkpoint {
                    seconds: statistics.render_seconds,
                    spp: statistics.passes,
                    counters: statistics.counters,
                    error,
                });
            }
        }
    }
    Ok((image, statistics, checkpoints))
}

/// Where the learned shares use their strategies: cells with a share above 0 of each grid.
fn describe_shares(prepared: &Prepared, method: Method) -> Option<String> {
    if !method.uses_guide() {
        return None;
    }
    let guide =
        prepared.guide_shares.as_ref().map(|s| format!("guide in {} of {} cells", s.cells_in_use(), s.cell_count()));
    let focal = prepared.focal_guide.as_ref().map(|f| {
        let (used, cells) = f.selection_cells();
        format!("focal boxes ({}) in {used} of {cells} cells", f.boxes().len())
    });
    let parts: Vec<String> = guide.into_iter().chain(focal).collect();
    (!parts.is_empty()).then(|| parts.join(", "))
}

fn sibling(path: &Path, extension: &str) -> PathBuf {
    path.with_extension(extension)
}

fn write_outputs(out: &Path, image: &Image, pfm: bool) -> Result<(), String> {
    if let Some(folder) = out.parent().filter(|f| !f.as_os_str().is_empty()) {
        std::fs::create_dir_all(folder).map_err(|e| format!("cannot create {}: {e}", folder.display()))?;
    }
    write_exr(out, image)?;
    write_png(&sibling(out, "png"), image)?;
    if pfm {
        write_pfm(&sibling(out, "pfm"), image)?;
    }
    Ok(())
}

/// The statistics JSON written beside every render.
pub fn statistics_json(
    method: Method,
    prepared: &Prepared,
    statistics: &RenderStatistics,
    image: &Image,
    threads: usize,
) -> serde_json::Value {
    let c = &statistics.counters;
    let seconds = statistics.render_seconds.max(1e-9);
    let mean = image.mean();
    let guide = prepared.guide.as_ref().filter(|_| method.uses_guide()).map(|g| {
        let s = g.stats();
        serde_json::json!({
            "structure": g.structure().name(),
            "regions": s.regions,
            "entries_per_region": s.entries_per_region,
            "memory_bytes": s.memory_bytes,
            "accepted_updates": s.accepted_updates,
            "visited_entries": s.visited_entries,
            "rejected_non_finite": s.rejected_non_finite,
            "rejected_negative": s.rejected_negative,
            "epochs": s.epochs,
        })
    });
    let light_guide = prepared.light_guide.as_ref().map(|g| {
        serde_json::json!({
            "cells": g.resolution(),
            "lights": g.light_count(),
            "memory_bytes": g.memory_bytes(),
            "rejected_updates": g.rejected_updates(),
        })
    });
    let gate = prepared.gate.as_ref().map(|g| {
        serde_json::json!({
            "cells": g.resolution(),
            "memory_bytes": g.memory_bytes(),
        })
    });
    let environment_guide = prepared.environment_guide.as_ref().map(|g| {
        serde_json::json!({
            "cells": g.resolution(),
            "tiles": g.tiles().tiles(),
            "sun": g.sun().is_some(),
            "table_bytes": g.table_bytes(),
            "memory_bytes": g.memory_bytes(),
            "rejected_updates": g.rejected_updates(),
        })
    });
    serde_json::json!({
        "scene": prepared.scene.path.display().to_string(),
        "method": method.name(),
        "plan": prepared.plan.describe(),
        "learned": prepared.guide.as_ref().filter(|_| method.uses_guide()).map(|g| g.describe()),
        "shares": describe_shares(prepared, method),
        "light_guide": light_guide,
        "next_event_gate": gate,
        "environment_guide": environment_guide,
        "width": image.width,
        "height": image.height,
        "passes": statistics.passes,
        "training_passes": statistics.training_passes,
        "training_seconds": statistics.training_seconds,
        "kept_paths_per_second": statistics.kept_paths_per_second(),
        "spp": statistics.passes,
        "paths": c.paths,
        "rays": c.rays,
        "nonzero_share": c.nonzero_paths as f64 / c.paths.max(1) as f64,
        "mean_path_length": c.vertices as f64 / c.paths.max(1) as f64,
        "paths_per_second": c.paths as f64 / seconds,
        "rays_per_second": c.rays as f64 / seconds,
        "mean_radiance": [mean.x, mean.y, mean.z],
        "time": {
            "load_seconds": prepared.times.load,
            "bvh_seconds": prepared.times.bvh,
            "guide_build_seconds": prepared.times.guide,
            "render_seconds": statistics.render_seconds,
            "guide_rebuild_seconds": statistics.guide_rebuild_seconds,
            // Thread-seconds in guide calls (locate, estimate, sample, pdf, update),
            // extrapolated from timing 1 path in 64; divide by the thread count for wall time.
            "guide_call_thread_seconds": c.estimated_guide_seconds(),
            "threads": threads,
        },
        "guide": guide,
        "warnings": prepared.scene.warnings,
        "pass_means": statistics.pass_means,
    })
}

fn run_render(args: &RenderArgs) -> Result<(), String> {
    let options = &args.options;
    let guide = options.directional_guide(args.integrator, options.single_guide()?)?;
    let budget = match (args.spp, args.seconds) {
        (Some(0), _) => return Err("--spp must be at least 1".into()),
        (Some(spp), _) => Budget::SamplesPerPixel(spp),
        (None, Some(s)) if s.is_finite() && s > 0.0 => Budget::Seconds(s),
        (None, Some(s)) => return Err(format!("--seconds {s} must be positive")),
        (None, None) => Budget::SamplesPerPixel(64),
    };
    let reference = match &args.reference {
        Some(path) => Some(read_image(path).map_err(|e| format!("{}: {e}", path.display()))?),
        None => None,
    };
    let pool = thread_pool(options.threads)?;
    let mut prepared =
        prepare_with_lights(&args.scene, options.intersector, guide, options.light_request(args.integrator)?)?;
    resize(&mut prepared, options.resolution);
    prepared.device = options.device;
    prepared.focal_settings = options.focal_settings()?;
    prepared.guide_share_cost = options.guide_share_cost;
    for warning in &prepared.scene.warnings {
        eprintln!("warning: {}: {warning}", args.scene.display());
    }
    eprintln!("plan: {}", prepared.plan.describe());
    if let Some(reference) = &reference {
        let camera = &prepared.scene.camera;
        if (reference.width, reference.height) != (camera.width as usize, camera.height as usize) {
            return Err(format!(
                "reference is {}×{}, the scene renders {}×{}",
                reference.width, reference.height, camera.width, camera.height
            ));
        }
    }
    let settings = RenderSettings {
        integrator: options.integrator(args.integrator, &prepared.plan),
        budget,
        seed: options.seed,
        train_seconds: options.train_seconds,
        schedule: options.schedule(),
        combine: options.combine,
    };
    let (image, statistics, checkpoints) =
        pool.install(|| render_prepared(&mut prepared, &settings, reference.as_ref(), &[], true))?;
    write_outputs(&args.out, &image, args.pfm)?;
    let json = statistics_json(args.integrator, &prepared, &statistics, &image, pool.current_num_threads());
    let json_path = sibling(&args.out, "json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&json).unwrap_or_default())
        .map_err(|e| format!("cannot write {}: {e}", json_path.display()))?;
    if reference.is_some() {
        let rows = crate::report::checkpoint_rows(args.integrator.name(), &checkpoints);
        crate::report::write_csv(&sibling(&args.out, "csv"), &rows)?;
        let title = format!("{}: relMSE against time", args.scene.display());
        crate::report::plot_svg(&sibling(&args.out, "svg"), &rows, &[args.integrator.name().to_string()], &title)?;
    }
    let c = &statistics.counters;
    eprintln!(
        "{}: {} spp in {:.2} s, {:.0} paths/s, non-zero share {:.3}, mean path length {:.2}{}",
        args.integrator.name(),
        statistics.passes,
        statistics.render_seconds,
        c.paths as f64 / statistics.render_seconds.max(1e-9),
        c.nonzero_paths as f64 / c.paths.max(1) as f64,
        c.vertices as f64 / c.paths.max(1) as f64,
        checkpoints.last().map(|c| format!(", relMSE {:.4e}", c.error.relmse)).unwrap_or_default()
    );
    if statistics.training_passes > 0 {
        eprintln!(
            "training: {} passes in {:.2} s; the kept passes ran at {:.0} paths/s",
            statistics.training_passes,
            statistics.training_seconds,
            statistics.kept_paths_per_second()
        );
    }
    if let Some(guide) = prepared.guide.as_ref().filter(|_| args.integrator.uses_guide()) {
        eprintln!("learned: {}", guide.describe());
    }
    if let Some(shares) = describe_shares(&prepared, args.integrator) {
        eprintln!("shares: {shares}");
    }
    eprintln!("wrote {}", args.out.display());
    Ok(())
}

fn run_reference(args: &ReferenceArgs) -> Result<(), String> {
    if args.spp == 0 {
        return Err("--spp must be at least 1".into());
    }
    let pool = thread_pool(args.threads)?;
    let guide = args.integrator.uses_guide().then(|| HemisphereGridSettings::default().into());
    let lights = LightRequest::new(Some(args.light_selection), Some(args.env_sampling), args.integrator.uses_nee());
    let mut prepared = prepare_with_lights(&args.scene, IntersectorChoice::fastest(), guide, lights)?;
    resize(&mut prepared, args.resolution);
    let integrator = IntegratorSettings {
        method: args.integrator,
        light_selection: args.light_selection,
        environment_sampling: args.env_sampling,
        ..Default::default()
    };
    let settings = RenderSettings {
        integrator,
        budget: Budget::SamplesPerPixel(args.spp),
        seed: args.seed,
        train_seconds: 0.0,
        schedule: Schedule::Online,
        combine: Combine::default(),
    };
    let (image, statistics, _) = pool.install(|| render_prepared(&mut prepared, &settings, None, &[], true))?;
    write_outputs(&args.out, &image, args.pfm)?;
    let json = statistics_json(args.integrator, &prepared, &statistics, &image, pool.current_num_threads());
    std::fs::write(sibling(&args.out, "json"), serde_json::to_string_pretty(&json).unwrap_or_default())
        .map_err(|e| format!("cannot write statistics: {e}"))?;
    eprintln!(
        "reference: {} spp in {:.1} s, wrote {}",
        statistics.passes,
        statistics.render_seconds,
        args.out.display()
    );
    Ok(())
}

fn run_compare(args: &CompareArgs) -> Result<(), String> {
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        return Err(format!("--seconds {} must be positive", args.seconds));
    }
    let options = &args.options;
    let reference = read_image(&args.reference).map_err(|e| format!("{}: {e}", args.reference.display()))?;
    std::fs::create_dir_all(&args.out).map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut report_times: Vec<f64> = if args.report_at.is_empty() {
        [10.0, args.seconds].into_iter().filter(|&t| t <= args.seconds).collect()
    } else {
        args.report_at.clone()
    };
    report_times.dedup();
    let pool = thread_pool(options.threads)?;
    let mut rows = Vec::new();
    let mut names = Vec::new();
    let mut learned_bytes = Vec::new();
    if let Some(peer) = args.peer {
        eprintln!("{}: rendering {} s", peer.name(), args.seconds);
        let settings = PeerSettings {
            max_depth: options.max_depth,
            rr_depth: options.rr_depth,
            resolution: options.resolution,
            threads: options.threads,
        };
        rows.extend(run_peer(peer, &args.scene, args.seconds, settings, &args.out, &reference, &report_times)?);
        names.push(peer.name().to_string());
        learned_bytes.push(0);
    }
    for run in expand_guides(&args.methods, &options.guide) {
        let (compared, name) = (run.compared, run.name);
        let method = compared.method;
        let mut options = options.clone();
        options.device = compared.device;
        options.light_selection = Auto(compared.selection.or(options.light_selection.0));
        options.env_sampling = Auto(compared.environment.or(options.env_sampling.0));
        let mut prepared = prepare_with_lights(
            &args.scene,
            options.intersector,
            options.directional_guide(method, run.guide)?,
            options.light_request(method)?,
        )?;
        resize(&mut prepared, options.resolution);
        prepared.device = compared.device;
        prepared.focal_settings = options.focal_settings()?;
        prepared.guide_share_cost = options.guide_share_cost;
        eprintln!("{name}: plan: {}", prepared.plan.describe());
        let camera = &prepared.scene.camera;
        if (reference.width, reference.height) != (camera.width as usize, camera.height as usize) {
            return Err(format!(
                "reference is {}×{}, the scene renders {}×{}",
                reference.width, reference.height, camera.width, camera.height
            ));
        }
        eprintln!("{name}: rendering {} s", args.seconds);
        let settings = RenderSettings {
            integrator: options.integrator(method, &prepared.plan),
            budget: Budget::Seconds(args.seconds),
            seed: options.seed,
            train_seconds: options.train_seconds,
            schedule: options.schedule(),
            combine: options.combine,
        };
        let (image, statistics, checkpoints) =
            pool.install(|| render_prepared(&mut prepared, &settings, Some(&reference), &report_times, true))?;
        let image_path = args.out.join(format!("{}.exr", name.replace([':', '+'], "-")));
        write_outputs(&image_path, &image, false)?;
        let json = statistics_json(method, &prepared, &statistics, &image, pool.current_num_threads());
        std::fs::write(sibling(&image_path, "json"), serde_json::to_string_pretty(&json).unwrap_or_default())
            .map_err(|e| format!("cannot write statistics: {e}"))?;
        rows.extend(crate::report::checkpoint_rows(&name, &checkpoints));
        learned_bytes.push(prepared.learned_bytes(method));
        names.push(name);
    }
    crate::report::write_csv(&args.out.join("compare.csv"), &rows)?;
    let baseline = if names.iter().any(|n| n == "nee") { "nee" } else { names[0].as_str() };
    let table = crate::report::markdown(&rows, &names, &learned_bytes, &report_times, baseline);
    let title = format!("{}: relMSE against time", args.scene.display());
    let markdown =
        format!("# {title}\n\n{} s per method, reference {}\n\n{table}", args.seconds, args.reference.display());
    std::fs::write(args.out.join("compare.md"), &markdown).map_err(|e| format!("cannot write compare.md: {e}"))?;
    crate::report::plot_svg(&args.out.join("error.svg"), &rows, &names, &title)?;
    println!("{table}");
    Ok(())
}

/// One render of `compare`: a method, the guide it runs with, and its name.
struct CompareRun {
    compared: ComparedMethod,
    guide: GuideChoice,
    name: String,
}

/// Each guided method once per entry of `--guide` (named METHOD@STRUCTURE when the list
/// has more than one), unless it named its own structure; unguided methods run once.
fn expand_guides(methods: &[ComparedMethod], choices: &[GuideChoice]) -> Vec<CompareRun> {
    let mut runs = Vec::new();
    for &compared in methods {
        match compared.guide {
            _ if !compared.method.uses_guide() => {
                runs.push(CompareRun { compared, guide: GuideChoice::Off, name: compared.name() })
            }
            Some(structure) => {
                runs.push(CompareRun { compared, guide: GuideChoice::Structure(structure), name: compared.name() })
            }
            None => {
                for &guide in choices {
                    let name = match (choices.len(), guide.structure()) {
                        (1, _) => compared.name(),
                        (_, Some(structure)) => format!("{}@{}", compared.name(), structure.name()),
                        (_, None) => format!("{}@none", compared.name()),
                    };
                    runs.push(CompareRun { compared, guide, name });
                }
            }
        }
    }
    runs
}

impl Cli {
    /// Runs the parsed command.
    pub fn run(&self) -> Result<(), String> {
        match &self.command {
            Command::Render(args) => run_render(args),
            Command::Reference(args) => run_reference(args),
            Command::Compare(args) => run_compare(args),
            Command::Convert(args) => run_convert(args),
        }
    }
}
