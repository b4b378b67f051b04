//! `lodestar convert`: a pbrt-v3 or Mitsuba scene written in the project's JSON format.

use std::path::PathBuf;

use clap::Args;

#[derive(Debug, Args)]
pub(super) struct ConvertArgs {
    /// The scene to read (.pbrt or .xml).
    pub(super) input: PathBuf,
    /// The JSON scene to write.
    pub(super) output: PathBuf,
}

pub(super) fn run_convert(args: &ConvertArgs) -> Result<(), String> {
    let warnings = crate::import::convert(&args.input, &args.output).map_err(|e| e.to_string())?;
    for warning in &warnings {
        eprintln!("warning: {warning}");
    }
    eprintln!("wrote {}", args.output.display());
    Ok(())
}
