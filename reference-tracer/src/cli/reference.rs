//! `lodestar reference`: a converged reference image.

use std::path::PathBuf;

use crate::scene_intersector::IntersectorChoice;
use clap::Args;
use guiding_core::HemisphereGridSettings;

use super::options::{parse_method, parse_resolution};
use super::outputs::{sibling, statistics_json, write_outputs};
use super::progressive::{render_session, thread_pool};
use crate::film::Combine;
use crate::integrator::{EnvironmentSampling, IntegratorSettings, LightSelection, Method};
use crate::render::{Budget, RenderSettings};
use crate::schedule::Schedule;
use crate::session::{prepare_with_lights, LightRequest};

#[derive(Debug, Args)]
pub(super) struct ReferenceArgs {
    /// The scene file: scene.json, or a pbrt-v3 (.pbrt) or Mitsuba (.xml) scene.
    pub(super) scene: PathBuf,
    /// Samples per pixel.
    #[arg(long)]
    pub(super) spp: u32,
    /// Any unbiased integrator; guided-nee converges fastest on hard scenes.
    #[arg(long, default_value = "nee", value_parser = parse_method)]
    pub(super) integrator: Method,
    /// Light selection (learned converges fastest with many occluded lights).
    #[arg(long, default_value = "power", value_parser = LightSelection::from_name)]
    pub(super) light_selection: LightSelection,
    /// Environment sampling (tiles converges fastest where most of the sky is hidden).
    #[arg(long, default_value = "luminance", value_parser = EnvironmentSampling::from_name)]
    pub(super) env_sampling: EnvironmentSampling,
    /// Output image (.exr).
    #[arg(long)]
    pub(super) out: PathBuf,
    /// Also write REF.pfm.
    #[arg(long)]
    pub(super) pfm: bool,
    /// Random seed.
    #[arg(long, default_value_t = 7)]
    pub(super) seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(super) threads: Option<usize>,
    /// Image size W×H instead of the scene's (same vertical field of view).
    #[arg(long, value_parser = parse_resolution)]
    pub(super) resolution: Option<[u32; 2]>,
}

pub(super) fn run_reference(args: &ReferenceArgs) -> Result<(), String> {
    if args.spp == 0 {
        return Err("--spp must be at least 1".into());
    }
    let pool = thread_pool(args.threads)?;
    let guide = args.integrator.uses_guide().then(|| HemisphereGridSettings::default().into());
    let lights = LightRequest::new(Some(args.light_selection), Some(args.env_sampling), args.integrator.uses_nee());
    let mut session = prepare_with_lights(&args.scene, IntersectorChoice::fastest(), guide, lights)?;
    session.resize(args.resolution);
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
        training_share: crate::schedule::DEFAULT_TRAINING_SHARE,
    };
    let (image, statistics, _) = pool.install(|| render_session(&mut session, &settings, None, &[], true))?;
    write_outputs(&args.out, &image, args.pfm)?;
    let json = statistics_json(args.integrator, &session, &statistics, &image, pool.current_num_threads());
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
