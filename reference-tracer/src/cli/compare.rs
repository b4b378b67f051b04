//! `lodestar compare`: several methods on one scene for the same wall time each.

use std::path::PathBuf;

use clap::Args;

use super::options::{parse_method, Auto, GuideChoice, TraceOptions};
use super::outputs::{sibling, statistics_json, write_outputs};
use super::progressive::{render_session, thread_pool};
use crate::backend::Device;
use crate::directional_guide::GuideStructure;
use crate::integrator::{EnvironmentSampling, LightSelection, Method};
use crate::output::read_image;
use crate::peer::{run_peer, Peer, PeerSettings};
use crate::render::{Budget, RenderSettings};
use crate::session::prepare_with_lights;

#[derive(Debug, Args)]
pub(super) struct CompareArgs {
    /// The scene file: scene.json, or a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene.
    pub(super) scene: PathBuf,
    /// Comma-separated methods, e.g. pt,nee,guided,guided-nee; a method may name its
    /// light selection, e.g. nee:uniform,nee:power,nee:learned (else --light-selection),
    /// its environment sampling, e.g. nee+luminance,nee+tiles (else --env-sampling), and
    /// its guide structure, e.g. guided-nee@mixture (else every one --guide lists), and
    /// the GPU tracer before it, e.g. gpu:nee (the `gpu` feature).
    #[arg(long, value_delimiter = ',', value_parser = parse_compared_method, required = true)]
    pub(super) methods: Vec<ComparedMethod>,
    /// Wall-clock seconds per method.
    #[arg(long)]
    pub(super) seconds: f64,
    /// Reference image (.exr/.pfm/.hdr).
    #[arg(long)]
    pub(super) reference: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub(super) out: PathBuf,
    /// Times (seconds) at which the table reports relMSE; default 10 and --seconds.
    #[arg(long, value_delimiter = ',')]
    pub(super) report_at: Vec<f64>,
    /// A peer renderer run first, for --seconds, as one more row: mitsuba (Mitsuba 3's
    /// vectorised path tracer, installed by scripts/peer-mitsuba.sh into .cache on first
    /// use; a scene it cannot render alike is refused with the feature named). It gets
    /// --max-depth, --rr-depth, --resolution and --threads.
    #[arg(long, value_parser = Peer::from_name)]
    pub(super) peer: Option<Peer>,
    #[command(flatten)]
    pub(super) options: TraceOptions,
}

/// One method of `compare`: METHOD[:LIGHT_SELECTION][+ENVIRONMENT_SAMPLING][@GUIDE].
#[derive(Clone, Copy, Debug)]
pub(super) struct ComparedMethod {
    /// Where it traces (`gpu:` before the method).
    pub(super) device: Device,
    pub(super) method: Method,
    pub(super) selection: Option<LightSelection>,
    pub(super) environment: Option<EnvironmentSampling>,
    pub(super) guide: Option<GuideStructure>,
}

impl ComparedMethod {
    /// The name it was given (and its output files take).
    pub(super) fn name(&self) -> String {
        let selection = self.selection.map(|s| format!(":{}", s.name())).unwrap_or_default();
        let environment = self.environment.map(|e| format!("+{}", e.name())).unwrap_or_default();
        let guide = self.guide.map(|g| format!("@{}", g.name())).unwrap_or_default();
        let device = if self.device == Device::Gpu { "gpu:" } else { "" };
        format!("{device}{}{selection}{environment}{guide}", self.method.name())
    }
}

pub(super) fn parse_compared_method(s: &str) -> Result<ComparedMethod, String> {
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

pub(super) fn run_compare(args: &CompareArgs) -> Result<(), String> {
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
        let mut session = prepare_with_lights(
            &args.scene,
            options.intersector,
            options.directional_guide(method, run.guide)?,
            options.light_request(method)?,
        )?;
        session.resize(options.resolution);
        session.device = compared.device;
        session.learners.focal_settings = options.focal_settings(method)?;
        session.learners.guide_share_cost = options.guide_share_cost;
        eprintln!("{name}: plan: {}", session.plan.describe());
        let camera = &session.scene.camera;
        if (reference.width, reference.height) != (camera.width as usize, camera.height as usize) {
            return Err(format!(
                "reference is {}×{}, the scene renders {}×{}",
                reference.width, reference.height, camera.width, camera.height
            ));
        }
        eprintln!("{name}: rendering {} s", args.seconds);
        let settings = RenderSettings {
            integrator: options.integrator(method, &session.plan),
            budget: Budget::Seconds(args.seconds),
            seed: options.seed,
            train_seconds: options.train_seconds,
            schedule: options.schedule(),
            combine: options.combine,
            training_share: options.train_share(method),
        };
        let (image, statistics, checkpoints) =
            pool.install(|| render_session(&mut session, &settings, Some(&reference), &report_times, true))?;
        let image_path = args.out.join(format!("{}.exr", name.replace([':', '+'], "-")));
        write_outputs(&image_path, &image, false)?;
        let json = statistics_json(method, &session, &statistics, &image, pool.current_num_threads());
        std::fs::write(sibling(&image_path, "json"), serde_json::to_string_pretty(&json).unwrap_or_default())
            .map_err(|e| format!("cannot write statistics: {e}"))?;
        rows.extend(crate::report::checkpoint_rows(&name, &checkpoints));
        learned_bytes.push(session.learned_bytes(method));
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
pub(super) struct CompareRun {
    pub(super) compared: ComparedMethod,
    pub(super) guide: GuideChoice,
    pub(super) name: String,
}

/// Each guided method once per entry of `--guide` (named METHOD@STRUCTURE when the list
/// has more than one), unless it named its own structure; unguided methods run once.
pub(super) fn expand_guides(methods: &[ComparedMethod], choices: &[GuideChoice]) -> Vec<CompareRun> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_compared_method_names_its_device_selection_environment_and_guide() {
        let m = parse_compared_method("gpu:nee:uniform+tiles@tree").unwrap();
        assert_eq!((m.device, m.method), (Device::Gpu, Method::Nee));
        assert_eq!(m.selection, Some(LightSelection::Uniform));
        assert_eq!(m.environment, Some(EnvironmentSampling::Tiles));
        assert_eq!(m.guide, Some(GuideStructure::Tree));
        let plain = parse_compared_method("guided-nee").unwrap();
        assert_eq!((plain.device, plain.method, plain.guide), (Device::Cpu, Method::GuidedNee, None));
        for bad in ["nee:sometimes", "guided@octopus", "nee+fog", "warp", "gpu:"] {
            assert!(parse_compared_method(bad).is_err(), "{bad} was accepted");
        }
    }

    #[test]
    fn guided_methods_run_once_per_listed_guide_and_unguided_ones_once() {
        let methods = ["nee", "guided-nee", "guided@volume"].map(|m| parse_compared_method(m).unwrap());
        let choices = [GuideChoice::Auto, GuideChoice::Structure(GuideStructure::Tree), GuideChoice::Off];
        let names: Vec<String> = expand_guides(&methods, &choices).into_iter().map(|run| run.name).collect();
        assert_eq!(names, ["nee", "guided-nee@hemisphere", "guided-nee@tree", "guided-nee@none", "guided@volume"]);
        let one: Vec<String> = expand_guides(&methods[1..2], &choices[1..2]).into_iter().map(|run| run.name).collect();
        assert_eq!(one, ["guided-nee"], "a single guide is not named");
    }
}
