//! The `lodestar` command line: the commands, one file each, and what they share:
//! the tracing options and their translation into settings, the progressive
//! render and its outputs. The session they render (scene, learners, backends) is
//! [`crate::session`].

mod compare;
mod convert;
mod merge_guides;
mod options;
mod outputs;
mod progressive;
mod reference;
mod render;
mod settings;

pub use options::{GuideShare, TraceOptions, GUIDE_SHARE_COST};
pub use outputs::statistics_json;
pub use progressive::render_session;

use clap::{Parser, Subcommand};

use compare::{run_compare, CompareArgs};
use convert::{run_convert, ConvertArgs};
use merge_guides::{run_merge_guides, MergeGuidesArgs};
use reference::{run_reference, ReferenceArgs};
use render::{run_render, RenderArgs};

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
    /// Combine guides saved by `render --save-guide` from renders of the same scene (a
    /// render farm's nodes, or processes with other seeds) into one.
    MergeGuides(MergeGuidesArgs),
}

impl Cli {
    /// Runs the parsed command.
    pub fn run(&self) -> Result<(), String> {
        match &self.command {
            Command::Render(args) => run_render(args),
            Command::Reference(args) => run_reference(args),
            Command::Compare(args) => run_compare(args),
            Command::Convert(args) => run_convert(args),
            Command::MergeGuides(args) => run_merge_guides(args),
        }
    }
}
