//! What a render writes: the images beside each other and the statistics JSON.

use std::path::{Path, PathBuf};

use super::progressive::describe_shares;
use crate::integrator::Method;
use crate::output::{write_exr, write_pfm, write_png, Image};
use crate::render::RenderStatistics;
use crate::session::Session;

pub(super) fn sibling(path: &Path, extension: &str) -> PathBuf {
    path.with_extension(extension)
}

pub(super) fn write_outputs(out: &Path, image: &Image, pfm: bool) -> Result<(), String> {
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
    session: &Session,
    statistics: &RenderStatistics,
    image: &Image,
    threads: usize,
) -> serde_json::Value {
    let c = &statistics.counters;
    let seconds = statistics.render_seconds.max(1e-9);
    let mean = image.mean();
    let guide = session.learners.guide_for(method).map(|g| {
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
    let light_guide = session.learners.light_guide.as_ref().map(|g| {
        serde_json::json!({
            "cells": g.resolution(),
            "lights": g.light_count(),
            "memory_bytes": g.memory_bytes(),
            "rejected_updates": g.rejected_updates(),
        })
    });
    let gate = session.learners.gate.as_ref().map(|g| {
        serde_json::json!({
            "cells": g.resolution(),
            "memory_bytes": g.memory_bytes(),
        })
    });
    let environment_guide = session.learners.environment_guide.as_ref().map(|g| {
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
        "scene": session.scene.path.display().to_string(),
        "method": method.name(),
        "plan": session.plan.describe(),
        "learned": session.learners.guide_for(method).map(|g| g.describe()),
        "shares": describe_shares(session, method),
        "light_guide": light_guide,
        "next_event_gate": gate,
        "environment_guide": environment_guide,
        "width": image.width,
        "height": image.height,
        "passes": statistics.passes,
        "training_passes": statistics.training_passes,
        "training_stopped_idle": statistics.training_stopped_idle,
        "lost_records": statistics.lost_records,
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
            "load_seconds": session.times.load,
            "bvh_seconds": session.times.bvh,
            "guide_build_seconds": session.times.guide,
            "render_seconds": statistics.render_seconds,
            "guide_rebuild_seconds": statistics.guide_rebuild_seconds,
            // Thread-seconds in guide calls (locate, estimate, sample, pdf, update),
            // extrapolated from timing 1 path in 64; divide by the thread count for wall time.
            "guide_call_thread_seconds": c.estimated_guide_seconds(),
            "threads": threads,
        },
        "guide": guide,
        "warnings": session.scene.warnings,
        "pass_means": statistics.pass_means,
    })
}
