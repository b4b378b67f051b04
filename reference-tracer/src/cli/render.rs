//! `lodestar render`: one scene, one method, progressive, with its outputs.

use std::path::{Path, PathBuf};

use clap::Args;
use guiding_core::{EnvTileGuide, LightGuide};

use super::options::{parse_method, TraceOptions};
use super::outputs::{sibling, statistics_json, write_outputs};
use super::progressive::{describe_shares, render_session, thread_pool};
use crate::animation::frame_seed;
use crate::directional_guide::DirectionalGuide;
use crate::integrator::Method;
use crate::output::read_image;
use crate::output::Image;
use crate::render::{Budget, RenderSettings, RenderStatistics};
use crate::session::{prepare_with_lights, Session};

#[derive(Debug, Args)]
pub(super) struct RenderArgs {
    /// The scene file: scene.json, or a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene.
    pub(super) scene: PathBuf,
    /// pt, nee, guided, guided-nee, light (light tracing: paths from the area lights,
    /// each vertex connected to the camera; scenes without mirrors, glass or an
    /// environment), light-guided (light tracing guided by W, the importance learned
    /// from light paths), bdpt (bidirectional: a camera and a light subpath joined in
    /// every way, weighted by exact MIS; scenes without an environment), bdpt-guided
    /// (both subpaths guided, by Q and W), vpl (instant radiosity: virtual point lights
    /// from a few light subpaths per pass, gathered at the first surface; biased by its
    /// clamp, coherent across the frames of an animation) or vpl-guided (its light
    /// subpaths guided by W, learned from what each virtual light gave). Default
    /// guided-nee: at 60 s, with the guided defaults, its relMSE ÷ nee's was 0.268 and
    /// 0.286 on door 160×120 (seeds 41, 42), 0.888 and 0.912 on cornell 128²; six scenes
    /// in the README.
    #[arg(long, default_value = "guided-nee", value_parser = parse_method)]
    pub(super) integrator: Method,
    #[command(flatten)]
    pub(super) options: TraceOptions,
    /// Samples per pixel (default 64 unless --seconds is given).
    #[arg(long, conflicts_with = "seconds")]
    pub(super) spp: Option<u32>,
    /// Wall-clock seconds of rendering.
    #[arg(long)]
    pub(super) seconds: Option<f64>,
    /// Output image (.exr); .png and .json are written beside it.
    #[arg(long)]
    pub(super) out: PathBuf,
    /// Also write IMAGE.pfm.
    #[arg(long)]
    pub(super) pfm: bool,
    /// Reference image (.exr/.pfm/.hdr) for error against time (IMAGE.csv).
    #[arg(long)]
    pub(super) reference: Option<PathBuf>,
    /// Start from this saved directional guide (of the --guide structure) instead of an
    /// empty one: it keeps learning, as a fresh one would.
    #[arg(long)]
    pub(super) load_guide: Option<PathBuf>,
    /// Save the directional guide learned by the end of the render (guiding-core's byte
    /// image; `merge-guides` combines several).
    #[arg(long)]
    pub(super) save_guide: Option<PathBuf>,
    /// Start learned light selection from this saved light guide (`--save-light-guide`
    /// of a render of the same scene and settings) instead of an empty one.
    #[arg(long)]
    pub(super) load_light_guide: Option<PathBuf>,
    /// Save the light guide of learned light selection by the end of the render.
    #[arg(long)]
    pub(super) save_light_guide: Option<PathBuf>,
    /// Start environment sampling by tiles from this saved environment guide
    /// (`--save-env-guide` of a render of the same scene and settings).
    #[arg(long)]
    pub(super) load_env_guide: Option<PathBuf>,
    /// Save the environment-tile guide by the end of the render.
    #[arg(long)]
    pub(super) save_env_guide: Option<PathBuf>,
    /// Render an animation of this many frames along the camera's keyframes in the scene
    /// file (`camera.keyframes`), each with the whole --spp or --seconds, written as
    /// IMAGE-0000.exr, IMAGE-0001.exr, … (with their .png and .json); the --save-* flags
    /// save what the last frame ended with.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub(super) frames: u32,
    /// Animations: on keeps every learner (Q, W, light selection, the focal guide) from
    /// frame to frame and draws the same random numbers in every frame (instant
    /// radiosity's virtual lights stay where they were); off renders each frame as a
    /// separate render would, from empty learners with a seed of its own.
    #[arg(long, default_value = "on", action = clap::ArgAction::Set, value_parser = super::options::parse_switch)]
    pub(super) frame_coherence: bool,
}

pub(super) fn run_render(args: &RenderArgs) -> Result<(), String> {
    if args.frames > 1 {
        return run_animation(args);
    }
    let options = &args.options;
    let reference = match &args.reference {
        Some(path) => Some(read_image(path).map_err(|e| format!("{}: {e}", path.display()))?),
        None => None,
    };
    let pool = thread_pool(options.threads)?;
    let (mut session, settings) = prepare_render(args)?;
    if let Some(reference) = &reference {
        let camera = &session.scene.camera;
        if (reference.width, reference.height) != (camera.width as usize, camera.height as usize) {
            return Err(format!(
                "reference is {}×{}, the scene renders {}×{}",
                reference.width, reference.height, camera.width, camera.height
            ));
        }
    }
    check_save_targets(args, &session)?;
    let (image, statistics, checkpoints) =
        pool.install(|| render_session(&mut session, &settings, reference.as_ref(), &[], true))?;
    write_image_and_statistics(args, &args.out, &session, &statistics, &image, pool.current_num_threads())?;
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
            "training: {} passes in {:.2} s{}; the kept passes ran at {:.0} paths/s",
            statistics.training_passes,
            statistics.training_seconds,
            if statistics.training_stopped_idle { " (stopped early: guiding idled)" } else { "" },
            statistics.kept_paths_per_second()
        );
    }
    if let Some(guide) = session.learners.guide_for(args.integrator) {
        eprintln!("learned: {}", guide.describe());
    }
    if statistics.lost_records > 0 {
        eprintln!("lost: {} learning records past the GPU's record buffer", statistics.lost_records);
    }
    if let Some(shares) = describe_shares(&session, args.integrator) {
        eprintln!("shares: {shares}");
    }
    save_guides(args, &session)?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}

/// `--frames N`: the frames one after another, coherent or not (`--frame-coherence`).
fn run_animation(args: &RenderArgs) -> Result<(), String> {
    if let Some(path) = &args.reference {
        return Err(format!("--reference {}: an animation (--frames above 1) has no one reference", path.display()));
    }
    let pool = thread_pool(args.options.threads)?;
    let (mut session, settings) = prepare_render(args)?;
    if session.scene.camera_keyframes.is_empty() {
        eprintln!("warning: {}: the camera has no keyframes: every frame shows the same view", args.scene.display());
    }
    check_save_targets(args, &session)?;
    let coherent = args.frame_coherence;
    for frame in 0..args.frames {
        if frame > 0 && !coherent {
            // Empty learners, as a separate render would start from.
            session = prepare_render(args)?.0;
        }
        session.scene.camera = session.scene.frame_camera(frame, args.frames);
        let frame_settings = RenderSettings { seed: frame_seed(settings.seed, frame, coherent), ..settings };
        let (image, statistics, _) = pool.install(|| render_session(&mut session, &frame_settings, None, &[], true))?;
        let out = frame_path(&args.out, frame);
        write_image_and_statistics(args, &out, &session, &statistics, &image, pool.current_num_threads())?;
        eprintln!(
            "frame {frame}: {} spp in {:.2} s; wrote {}",
            statistics.passes,
            statistics.render_seconds,
            out.display()
        );
    }
    save_guides(args, &session)
}

/// IMAGE.exr (with its .png, and .pfm when asked) and IMAGE.json at `out`.
fn write_image_and_statistics(
    args: &RenderArgs,
    out: &Path,
    session: &Session,
    statistics: &RenderStatistics,
    image: &Image,
    threads: usize,
) -> Result<(), String> {
    write_outputs(out, image, args.pfm)?;
    let json = statistics_json(args.integrator, session, statistics, image, threads);
    let json_path = sibling(out, "json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&json).unwrap_or_default())
        .map_err(|e| format!("cannot write {}: {e}", json_path.display()))
}

/// IMAGE-NNNN.ext for frame NNNN of `out` (IMAGE.ext).
fn frame_path(out: &Path, frame: u32) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match out.extension() {
        Some(extension) => format!("{stem}-{frame:04}.{}", extension.to_string_lossy()),
        None => format!("{stem}-{frame:04}"),
    };
    out.with_file_name(name)
}

/// The scene with its intersector, plan and learners, and the render's settings.
fn prepare_render(args: &RenderArgs) -> Result<(Session, RenderSettings), String> {
    let options = &args.options;
    let guide = options.directional_guide(args.integrator, options.single_guide()?)?;
    let budget = match (args.spp, args.seconds) {
        (Some(0), _) => return Err("--spp must be at least 1".into()),
        (Some(spp), _) => Budget::SamplesPerPixel(spp),
        (None, Some(s)) if s.is_finite() && s > 0.0 => Budget::Seconds(s),
        (None, Some(s)) => return Err(format!("--seconds {s} must be positive")),
        (None, None) => Budget::SamplesPerPixel(64),
    };
    let mut session =
        prepare_with_lights(&args.scene, options.intersector, guide, options.light_request(args.integrator)?)?;
    session.resize(options.resolution);
    if let Some(path) = &args.load_guide {
        let Some(built) = &session.learners.guide else {
            return Err(format!("--load-guide {}: this render has no directional guide", path.display()));
        };
        let bytes = std::fs::read(path).map_err(|e| format!("--load-guide {}: {e}", path.display()))?;
        let loaded = DirectionalGuide::from_bytes(built.structure(), &bytes)
            .map_err(|e| format!("--load-guide {}: {e}", path.display()))?;
        session.learners.guide = Some(loaded);
    }
    load_sampling_guides(args, &mut session)?;
    session.device = options.device;
    session.learners.focal_settings = options.focal_settings(args.integrator)?;
    session.learners.guide_share_cost = options.guide_share_cost;
    for warning in &session.scene.warnings {
        eprintln!("warning: {}: {warning}", args.scene.display());
    }
    eprintln!("plan: {}", session.plan.describe());
    let settings = RenderSettings {
        integrator: options.integrator(args.integrator, &session.plan),
        budget,
        seed: options.seed,
        train_seconds: options.train_seconds,
        schedule: options.schedule(),
        combine: options.combine,
        training_share: options.train_share(args.integrator),
    };
    Ok((session, settings))
}

/// `--save-guide`, `--save-light-guide` and `--save-env-guide`.
fn save_guides(args: &RenderArgs, session: &Session) -> Result<(), String> {
    if let Some(path) = &args.save_guide {
        let Some(guide) = &session.learners.guide else {
            return Err(format!("--save-guide {}: {NO_GUIDE}", path.display()));
        };
        std::fs::write(path, guide.to_bytes()).map_err(|e| format!("--save-guide {}: {e}", path.display()))?;
        eprintln!("saved the guide to {}", path.display());
    }
    save_sampling_guides(args, session)
}

/// Why a render has no directional guide to save.
const NO_GUIDE: &str = "this render has no directional guide (a guided method and a --guide other than none)";
/// Why a render has no light guide to load into or save.
const NO_LIGHT_GUIDE: &str = "this render has no learned light selection (see the plan; --light-selection learned)";
/// Why a render has no environment guide to load into or save.
const NO_ENV_GUIDE: &str = "this render samples no environment by tiles (see the plan; --env-sampling tiles)";

/// `--load-light-guide` and `--load-env-guide`: each file is read and merged into the
/// guide the plan built, which is still empty: the merge is exact, and checks that the
/// file learned the same scene with the same settings.
fn load_sampling_guides(args: &RenderArgs, session: &mut Session) -> Result<(), String> {
    let read = |flag: &str, path: &Path| std::fs::read(path).map_err(|e| format!("{flag} {}: {e}", path.display()));
    if let Some(path) = &args.load_light_guide {
        let flag = "--load-light-guide";
        let Some(built) = session.learners.light_guide.as_mut() else {
            return Err(format!("{flag} {}: {NO_LIGHT_GUIDE}", path.display()));
        };
        let loaded =
            LightGuide::from_bytes(&read(flag, path)?).map_err(|e| format!("{flag} {}: {e}", path.display()))?;
        built.merge(&loaded).map_err(|e| format!("{flag} {}: {e}", path.display()))?;
    }
    if let Some(path) = &args.load_env_guide {
        let flag = "--load-env-guide";
        let Some(built) = session.learners.environment_guide.as_mut() else {
            return Err(format!("{flag} {}: {NO_ENV_GUIDE}", path.display()));
        };
        let bytes = read(flag, path)?;
        let loaded = EnvTileGuide::from_bytes(&bytes, built.tiles().clone(), built.sun().copied())
            .map_err(|e| format!("{flag} {}: {e}", path.display()))?;
        built.merge(&loaded).map_err(|e| format!("{flag} {}: {e}", path.display()))?;
    }
    Ok(())
}

/// The `--save-*` flags, checked before rendering so that a long render does not end
/// in an error: each must name a guide this render builds, in a folder that exists.
fn check_save_targets(args: &RenderArgs, session: &Session) -> Result<(), String> {
    let targets = [
        ("--save-guide", &args.save_guide, session.learners.guide_for(args.integrator).is_some(), NO_GUIDE),
        ("--save-light-guide", &args.save_light_guide, session.learners.light_guide.is_some(), NO_LIGHT_GUIDE),
        ("--save-env-guide", &args.save_env_guide, session.learners.environment_guide.is_some(), NO_ENV_GUIDE),
    ];
    for (flag, path, built, missing) in targets {
        let Some(path) = path else { continue };
        if !built {
            return Err(format!("{flag} {}: {missing}", path.display()));
        }
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !folder.is_dir() {
            return Err(format!("{flag} {}: the folder {} does not exist", path.display(), folder.display()));
        }
    }
    Ok(())
}

/// `--save-light-guide` and `--save-env-guide`.
fn save_sampling_guides(args: &RenderArgs, session: &Session) -> Result<(), String> {
    let write = |flag: &str, path: &Path, bytes: Option<Vec<u8>>, missing: &str| {
        let bytes = bytes.ok_or_else(|| format!("{flag} {}: {missing}", path.display()))?;
        std::fs::write(path, bytes).map_err(|e| format!("{flag} {}: {e}", path.display()))?;
        eprintln!(
            "saved the {} to {}",
            if flag.contains("light") { "light guide" } else { "environment guide" },
            path.display()
        );
        Ok::<(), String>(())
    };
    if let Some(path) = &args.save_light_guide {
        write(
            "--save-light-guide",
            path,
            session.learners.light_guide.as_ref().map(LightGuide::to_bytes),
            NO_LIGHT_GUIDE,
        )?;
    }
    if let Some(path) = &args.save_env_guide {
        write(
            "--save-env-guide",
            path,
            session.learners.environment_guide.as_ref().map(EnvTileGuide::to_bytes),
            NO_ENV_GUIDE,
        )?;
    }
    Ok(())
}
