//! Error-against-time reports: the CSV every comparison writes, a markdown summary and
//! a log-log SVG plot of relMSE against seconds, one line per method.

use std::path::Path;

use plotters::prelude::*;

use crate::metrics::ImageError;

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

/// One row of compare.csv.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportRow {
    /// Method (and guide) name.
    pub method: String,
    /// Seconds of rendering at the checkpoint.
    pub seconds: f64,
    /// Samples per pixel at the checkpoint.
    pub spp: u32,
    /// Paths per second up to the checkpoint.
    pub paths_per_second: f64,
    /// Share of paths with a non-zero contribution.
    pub nonzero_share: f64,
    /// Mean surface vertices per path.
    pub mean_path_length: f64,
    /// Relative MSE against the reference.
    pub relmse: f64,
    /// MSE against the reference.
    pub mse: f64,
    /// MAPE against the reference.
    pub mape: f64,
    /// The median pixel's relative squared error.
    pub median_relmse: f64,
    /// The share of the relMSE held by the worst 1 % of pixels.
    pub worst_share: f64,
}

/// The CSV header, fixed: scripts and tests read it.
pub const CSV_HEADER: &str =
    "method,seconds,spp,paths_per_second,nonzero_share,mean_path_length,relmse,mse,mape,median_relmse,worst_share";

/// Rows for one method's checkpoints.
pub fn checkpoint_rows(method: &str, checkpoints: &[Checkpoint]) -> Vec<ReportRow> {
    checkpoints
        .iter()
        .map(|c| {
            let paths = c.counters.paths.max(1) as f64;
            ReportRow {
                method: method.to_string(),
                seconds: c.seconds,
                spp: c.spp,
                paths_per_second: c.counters.paths as f64 / c.seconds.max(1e-9),
                nonzero_share: c.counters.nonzero_paths as f64 / paths,
                mean_path_length: c.counters.vertices as f64 / paths,
                relmse: c.error.relmse,
                mse: c.error.mse,
                mape: c.error.mape,
                median_relmse: c.error.median_relmse,
                worst_share: c.error.worst_share,
            }
        })
        .collect()
}

/// Writes rows under [`CSV_HEADER`].
pub fn write_csv(path: &Path, rows: &[ReportRow]) -> Result<(), String> {
    let mut text = format!("{CSV_HEADER}\n");
    for r in rows {
        text += &format!(
            "{},{:.6},{},{:.1},{:.6},{:.4},{:.6e},{:.6e},{:.6e},{:.6e},{:.6}\n",
            r.method,
            r.seconds,
            r.spp,
            r.paths_per_second,
            r.nonzero_share,
            r.mean_path_length,
            r.relmse,
            r.mse,
            r.mape,
            r.median_relmse,
            r.worst_share
        );
    }
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The first checkpoint of `method` at or after `seconds`.
fn at_time<'a>(rows: &'a [ReportRow], method: &str, seconds: f64) -> Option<&'a ReportRow> {
    rows.iter().filter(|r| r.method == method && r.seconds >= seconds).min_by(|a, b| a.seconds.total_cmp(&b.seconds))
}

/// A markdown summary: per method its final figures (with relMSE × spp, the error per
/// sample; the median pixel's error; the share of the worst 1 % of pixels) and the bytes
/// of what it learned (`learned_bytes[i]` for `methods[i]`), and relMSE at each of
/// `times` (the first checkpoint at or after it) with its ratio to `baseline`'s.
pub fn markdown(
    rows: &[ReportRow],
    methods: &[String],
    learned_bytes: &[usize],
    times: &[f64],
    baseline: &str,
) -> String {
    let mut text = String::from(
        "| method | spp | paths/s | non-zero share | mean path length | learned bytes | relMSE × spp | median | worst 1 % |",
    );
    for t in times {
        text += &format!(" relMSE @ {t} s | ÷ {baseline} |");
    }
    text += "\n|---|---|---|---|---|---|---|---|---|";
    text += &"---|---|".repeat(times.len());
    text += "\n";
    for (method, bytes) in methods.iter().zip(learned_bytes) {
        let Some(last) = rows.iter().filter(|r| &r.method == method).max_by(|a, b| a.seconds.total_cmp(&b.seconds))
        else {
            continue;
        };
        // A peer renderer reports neither.
        let shown = |v: f64, digits: usize| if v.is_finite() { format!("{v:.digits$}") } else { "–".into() };
        text += &format!(
            "| {method} | {} | {:.0} | {} | {} | {bytes} | {:.3} | {:.3e} | {:.3} |",
            last.spp,
            last.paths_per_second,
            shown(last.nonzero_share, 4),
            shown(last.mean_path_length, 2),
            last.relmse * last.spp as f64,
            last.median_relmse,
            last.worst_share
        );
        for &t in times {
            match (at_time(rows, method, t), at_time(rows, baseline, t)) {
                (Some(r), Some(b)) => {
                    text += &format!(" {:.4e} ({:.1} s) | {:.3} |", r.relmse, r.seconds, r.relmse / b.relmse)
                }
                (Some(r), None) => text += &format!(" {:.4e} ({:.1} s) | – |", r.relmse, r.seconds),
                _ => text += " – | – |",
            }
        }
        text += "\n";
    }
    text
}

/// Plots relMSE against seconds on log-log axes, one line per method.
pub fn plot_svg(path: &Path, rows: &[ReportRow], methods: &[String], title: &str) -> Result<(), String> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let points: Vec<&ReportRow> = rows.iter().filter(|r| positive(r.seconds) && positive(r.relmse)).collect();
    if points.is_empty() {
        return Err("no checkpoint with positive time and error to plot".into());
    }
    let (t0, t1) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), r| (lo.min(r.seconds), hi.max(r.seconds)));
    let (e0, e1) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), r| (lo.min(r.relmse), hi.max(r.relmse)));
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::new(path, (800, 500)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((t0 * 0.9..t1 * 1.1).log_scale(), (e0 * 0.8..e1 * 1.25).log_scale())?;
        chart.configure_mesh().x_desc("seconds").y_desc("relMSE").draw()?;
        for (i, method) in methods.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let series: Vec<(f64, f64)> =
                points.iter().filter(|r| &r.method == method).map(|r| (r.seconds, r.relmse)).collect();
            chart
                .draw_series(LineSeries::new(series.clone(), color.stroke_width(2)))?
                .label(method.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            chart.draw_series(series.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        }
        chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("cannot plot {}: {e}", path.display()))
}
