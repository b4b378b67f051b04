//! Rendering a session scene progressively: the thread pool, the progress bar and the
//! error-against-time checkpoints.

use indicatif::{ProgressBar, ProgressStyle};

use crate::integrator::Method;
use crate::metrics::image_error;
use crate::output::Image;
use crate::render::{Budget, RenderSettings, RenderStatistics};
use crate::report::Checkpoint;
use crate::session::Session;

pub(super) fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, String> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err("--threads must be at least 1".into());
        }
        builder = builder.num_threads(n);
    }
    builder.build().map_err(|e| format!("cannot start worker threads: {e}"))
}

pub(super) fn progress_bar(budget: Budget) -> ProgressBar {
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

/// Renders a session scene, recording the error against `reference` after passes
/// 1, 2, 4, 8, …, after the first pass to end at or past each of `report_times`
/// (seconds), and after the last.
pub fn render_session(
    session: &mut Session,
    settings: &RenderSettings,
    reference: Option<&Image>,
    report_times: &[f64],
    show_progress: bool,
) -> Result<(Image, RenderStatistics, Vec<Checkpoint>), String> {
    let bar = if show_progress { progress_bar(settings.budget) } else { ProgressBar::hidden() };
    let mut checkpoints = Vec::new();
    let mut previous_seconds = 0.0;
    let (image, statistics) = session.render(settings, |progress| {
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
pub(super) fn describe_shares(session: &Session, method: Method) -> Option<String> {
    if !method.uses_guide() {
        return None;
    }
    let guide = session
        .learners
        .guide_shares
        .as_ref()
        .map(|s| format!("guide in {} of {} cells", s.cells_in_use(), s.cell_count()));
    let focal = session.learners.focal_guide.as_ref().map(|f| {
        let (used, cells) = f.selection_cells();
        format!("focal boxes ({}) in {used} of {cells} cells", f.boxes().len())
    });
    let parts: Vec<String> = guide.into_iter().chain(focal).collect();
    (!parts.is_empty()).then(|| parts.join(", "))
}
