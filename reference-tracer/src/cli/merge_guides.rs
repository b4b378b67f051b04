//! `lodestar merge-guides`: what several renders (nodes of a render farm, or processes with
//! different seeds) learned, combined into one guide.

use std::path::PathBuf;

use clap::Args;

use crate::directional_guide::{DirectionalGuide, GuideStructure};

#[derive(Debug, Args)]
pub(super) struct MergeGuidesArgs {
    /// Guides saved by `render --save-guide`, all built over the same scene with the same
    /// settings.
    #[arg(required = true, num_args = 2..)]
    pub(super) guides: Vec<PathBuf>,
    /// Their structure (hemisphere is the only one that merges so far).
    #[arg(long, default_value = "hemisphere", value_parser = GuideStructure::from_name)]
    pub(super) guide: GuideStructure,
    /// The merged guide to write.
    #[arg(long)]
    pub(super) out: PathBuf,
}

pub(super) fn run_merge_guides(args: &MergeGuidesArgs) -> Result<(), String> {
    let read = |path: &PathBuf| -> Result<DirectionalGuide, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        DirectionalGuide::from_bytes(args.guide, &bytes).map_err(|e| format!("{}: {e}", path.display()))
    };
    let mut merged = read(&args.guides[0])?;
    for path in &args.guides[1..] {
        merged.merge(&read(path)?).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    std::fs::write(&args.out, merged.to_bytes()).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let stats = merged.stats();
    eprintln!(
        "merged {} guides: {} accepted updates in {} regions; wrote {}",
        args.guides.len(),
        stats.accepted_updates,
        stats.regions,
        args.out.display()
    );
    Ok(())
}
