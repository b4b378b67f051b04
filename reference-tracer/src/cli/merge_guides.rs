//! `lodestar merge-guides`: what several renders (nodes of a render farm, or processes with
//! different seeds) learned, combined into one guide: a directional guide, the light
//! guide of learned light selection, or the environment-tile guide.

use std::path::{Path, PathBuf};

use clap::Args;
use guiding_core::{EnvTileGuide, LightGuide};

use super::options::parse_patches;
use crate::directional_guide::{DirectionalGuide, GuideStructure};
use crate::scene::Scene;
use crate::session::environment_tiles;

/// Which guide the files hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum GuideKind {
    /// A directional guide of this structure (`--save-guide`).
    Directional(GuideStructure),
    /// A light guide (`--save-light-guide`).
    Lights,
    /// An environment-tile guide (`--save-env-guide`).
    Environment,
}

impl GuideKind {
    fn from_name(s: &str) -> Result<Self, String> {
        match s {
            "lights" => Ok(GuideKind::Lights),
            "environment" => Ok(GuideKind::Environment),
            _ => GuideStructure::from_name(s)
                .map(GuideKind::Directional)
                .map_err(|_| format!("unknown guide `{s}` ({}, lights, environment)", GuideStructure::names())),
        }
    }
}

#[derive(Debug, Args)]
pub(super) struct MergeGuidesArgs {
    /// Guides saved by `render` (`--save-guide`, `--save-light-guide` or
    /// `--save-env-guide`), all learned over the same scene with the same settings.
    #[arg(required = true, num_args = 2..)]
    pub(super) guides: Vec<PathBuf>,
    /// What they hold: a directional guide's structure (hemisphere, volume, mixture or
    /// tree), lights, or environment.
    #[arg(long, default_value = "hemisphere", value_parser = GuideKind::from_name)]
    pub(super) guide: GuideKind,
    /// The scene the guides learned: environment guides are read against its
    /// environment map (which they do not store).
    #[arg(long)]
    pub(super) scene: Option<PathBuf>,
    /// The environment tiles the guides were rendered with (`render --env-tiles`).
    #[arg(long, default_value = "32x16", value_parser = parse_patches)]
    pub(super) env_tiles: [u32; 2],
    /// The merged guide to write.
    #[arg(long)]
    pub(super) out: PathBuf,
}

pub(super) fn run_merge_guides(args: &MergeGuidesArgs) -> Result<(), String> {
    let (bytes, summary) = match args.guide {
        GuideKind::Directional(structure) => {
            let merged =
                merge_all(&args.guides, |bytes| DirectionalGuide::from_bytes(structure, bytes), |a, b| a.merge(b))?;
            let stats = merged.stats();
            (merged.to_bytes(), format!("{} accepted updates in {} regions", stats.accepted_updates, stats.regions))
        }
        GuideKind::Lights => {
            let merged = merge_all(
                &args.guides,
                |bytes| LightGuide::from_bytes(bytes).map_err(|e| e.to_string()),
                |a, b| a.merge(b).map_err(|e| e.to_string()),
            )?;
            let summary = format!("{} lights in {} cells", merged.light_count(), merged.cell_count());
            (merged.to_bytes(), summary)
        }
        GuideKind::Environment => {
            let Some(path) = &args.scene else {
                return Err("--guide environment needs --scene: the guides are read against its environment".into());
            };
            let scene = Scene::load(path).map_err(|e| format!("{}: {e}", path.display()))?;
            let Some(environment) = &scene.environment else {
                return Err(format!("{}: the scene has no environment", path.display()));
            };
            let (tiles, sun) = environment_tiles(environment, args.env_tiles)?;
            let merged = merge_all(
                &args.guides,
                |bytes| EnvTileGuide::from_bytes(bytes, tiles.clone(), sun).map_err(|e| e.to_string()),
                |a, b| a.merge(b).map_err(|e| e.to_string()),
            )?;
            let [u, v] = merged.tiles().tiles();
            (merged.to_bytes(), format!("{} cells × {u}×{v} tiles", merged.cell_count()))
        }
    };
    std::fs::write(&args.out, bytes).map_err(|e| format!("{}: {e}", args.out.display()))?;
    eprintln!("merged {} guides: {summary}; wrote {}", args.guides.len(), args.out.display());
    Ok(())
}

/// Reads every file with `read` and merges them in order into the first with `merge`;
/// an error names the file.
fn merge_all<G>(
    paths: &[PathBuf],
    read: impl Fn(&[u8]) -> Result<G, String>,
    merge: impl Fn(&mut G, &G) -> Result<(), String>,
) -> Result<G, String> {
    let load = |path: &Path| -> Result<G, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        read(&bytes).map_err(|e| format!("{}: {e}", path.display()))
    };
    let mut merged = load(&paths[0])?;
    for path in &paths[1..] {
        merge(&mut merged, &load(path)?).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(merged)
}
