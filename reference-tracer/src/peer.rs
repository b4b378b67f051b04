//! A peer renderer as rows of `lodestar compare`: Mitsuba 3's vectorised `path`
//! integrator (scripts/peer-mitsuba.sh), run on the same scene for the same seconds and
//! measured against the same reference, so Lodestar's tracer is judged beside the
//! fastest honest one.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::metrics::image_error;
use crate::output::{read_image, Image};
use crate::report::ReportRow;

/// A renderer `compare --peer` can run beside Lodestar's methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Peer {
    /// Mitsuba 3 (`llvm_ad_rgb`, `path` integrator), installed into a virtual environment
    /// by scripts/peer-mitsuba.sh.
    Mitsuba,
}

impl Peer {
    /// Every peer, in the order the command line lists them.
    pub const ALL: [Peer; 1] = [Peer::Mitsuba];

    /// The command-line name, also the row's name in the table.
    pub fn name(self) -> &'static str {
        match self {
            Peer::Mitsuba => "mitsuba",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|p| p.name() == name).ok_or_else(|| format!("unknown peer `{name}` (mitsuba)"))
    }

    /// The script that runs the peer: `LODESTAR_PEER_MITSUBA` where set, else the
    /// repository's scripts/peer-mitsuba.sh.
    pub fn script(self) -> PathBuf {
        match std::env::var_os("LODESTAR_PEER_MITSUBA") {
            Some(path) => PathBuf::from(path),
            None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/peer-mitsuba.sh"),
        }
    }
}

/// How the peer traces, in Lodestar's terms.
#[derive(Clone, Copy, Debug)]
pub struct PeerSettings {
    /// Most scattering vertices per path (Mitsuba's max_depth counts the camera segment
    /// too: it gets one more).
    pub max_depth: u32,
    /// Russian roulette from this vertex on (Mitsuba's rr_depth counts alike).
    pub rr_depth: u32,
    /// Image size instead of the scene's.
    pub resolution: Option<[u32; 2]>,
    /// Worker threads (the peer's default: all cores).
    pub threads: Option<usize>,
}

/// Runs `peer` on `scene` for `seconds`, writing its images into `out`, and measures each
/// of its checkpoints (the first pass to end at or past each of `report_times`, and the
/// last) against `reference`. A scene the peer cannot render alike is an error naming
/// what it refused.
pub fn run_peer(
    peer: Peer,
    scene: &Path,
    seconds: f64,
    settings: PeerSettings,
    out: &Path,
    reference: &Image,
    report_times: &[f64],
) -> Result<Vec<ReportRow>, String> {
    let script = peer.script();
    if !script.is_file() {
        return Err(format!("--peer {}: no script at {}", peer.name(), script.display()));
    }
    // The peer reads the project's JSON with every shape's material named: the scene is
    // written so (a pbrt or Mitsuba scene converted, an OBJ's MTL materials inline).
    let peer_scene = out.join(format!("{}-scene.json", peer.name()));
    crate::import::write_self_contained_json(scene, &peer_scene)
        .map_err(|e| format!("--peer {}: cannot write the scene for it: {e}", peer.name()))?;
    let image_path = out.join(format!("{}.exr", peer.name()));
    let mut command = Command::new("bash");
    command
        .arg(&script)
        .arg(&peer_scene)
        .arg(seconds.to_string())
        .arg(&image_path)
        .args(["--max-depth", &(settings.max_depth + 1).to_string()])
        .args(["--rr-depth", &settings.rr_depth.to_string()]);
    if let Some([w, h]) = settings.resolution {
        command.args(["--resolution", &format!("{w}x{h}")]);
    }
    if let Some(threads) = settings.threads {
        command.args(["--threads", &threads.to_string()]);
    }
    let times: Vec<String> = report_times.iter().map(|t| t.to_string()).collect();
    command.args(["--checkpoints", &times.join(",")]);
    let output =
        command.output().map_err(|e| format!("--peer {}: cannot run {}: {e}", peer.name(), script.display()))?;
    let messages = String::from_utf8_lossy(&output.stderr);
    if !output.status.success() {
        let refused = if output.status.code() == Some(2) { "refused the scene" } else { "failed" };
        return Err(format!("--peer {}: {refused} ({}): {}", peer.name(), output.status, messages.trim()));
    }
    eprint!("{messages}{}", String::from_utf8_lossy(&output.stdout));
    read_checkpoints(peer, &image_path.with_extension("json"), reference)
}

/// The rows of the peer's report at `report`: one per checkpoint it lists, each image
/// measured against `reference`.
fn read_checkpoints(peer: Peer, report: &Path, reference: &Image) -> Result<Vec<ReportRow>, String> {
    let bad = |what: String| format!("--peer {}: {}: {what}", peer.name(), report.display());
    let text = std::fs::read_to_string(report).map_err(|e| bad(e.to_string()))?;
    let json: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let checkpoints = json["checkpoints"].as_array().ok_or_else(|| bad("no `checkpoints` list".into()))?;
    let mut rows = Vec::new();
    for (i, checkpoint) in checkpoints.iter().enumerate() {
        let field = |name: &str| {
            checkpoint[name]
                .as_f64()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| bad(format!("checkpoints[{i}].{name} is not a positive number")))
        };
        let (seconds, spp) = (field("seconds")?, field("spp")?);
        let path = checkpoint["image"].as_str().ok_or_else(|| bad(format!("checkpoints[{i}].image is not a path")))?;
        let image = read_image(Path::new(path)).map_err(|e| bad(format!("checkpoints[{i}]: {path}: {e}")))?;
        let error = image_error(&image, reference).ok_or_else(|| {
            bad(format!(
                "checkpoints[{i}]: the image is {}×{}, the reference {}×{}",
                image.width, image.height, reference.width, reference.height
            ))
        })?;
        let paths = spp * (image.width * image.height) as f64;
        rows.push(ReportRow {
            method: peer.name().to_string(),
            seconds,
            spp: spp as u32,
            paths_per_second: paths / seconds,
            // The peer does not report these.
            nonzero_share: f64::NAN,
            mean_path_length: f64::NAN,
            relmse: error.relmse,
            mse: error.mse,
            mape: error.mape,
            median_relmse: error.median_relmse,
            worst_share: error.worst_share,
        });
    }
    if rows.is_empty() {
        return Err(bad("an empty `checkpoints` list".into()));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn image(width: usize, height: usize, value: f32) -> Image {
        Image { width, height, pixels: vec![Vec3::splat(value); width * height] }
    }

    #[test]
    fn names_parse_and_unknown_ones_are_named() {
        assert_eq!(Peer::from_name("mitsuba"), Ok(Peer::Mitsuba));
        assert!(Peer::from_name("pbrt").unwrap_err().contains("`pbrt`"));
    }

    /// A report whose checkpoints point at images becomes one row each, with the error
    /// against the reference; a damaged report or a wrong-sized image is an error
    /// naming the field.
    #[test]
    fn checkpoints_become_rows_and_bad_reports_are_named() {
        let dir = std::env::temp_dir().join(format!("lodestar-peer-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let reference = image(4, 2, 1.0);
        let (half, exact) = (dir.join("half.exr"), dir.join("exact.exr"));
        crate::output::write_exr(&half, &image(4, 2, 0.5)).unwrap();
        crate::output::write_exr(&exact, &reference).unwrap();
        let report = dir.join("peer.json");
        let write = |json: serde_json::Value| std::fs::write(&report, json.to_string()).unwrap();
        write(serde_json::json!({"checkpoints": [
            {"seconds": 1.5, "spp": 3, "image": half},
            {"seconds": 4.0, "spp": 8, "image": exact},
        ]}));
        let rows = read_checkpoints(Peer::Mitsuba, &report, &reference).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!((rows[0].spp, rows[0].seconds), (3, 1.5));
        assert!((rows[0].relmse - 0.25 / 1.01).abs() < 1e-3, "{}", rows[0].relmse);
        assert_eq!(rows[1].relmse, 0.0);
        assert_eq!(rows[1].paths_per_second, 8.0 * 8.0 / 4.0);
        write(serde_json::json!({"checkpoints": [{"seconds": "soon", "spp": 3, "image": half}]}));
        let error = read_checkpoints(Peer::Mitsuba, &report, &reference).unwrap_err();
        assert!(error.contains("checkpoints[0].seconds"), "{error}");
        write(serde_json::json!({"checkpoints": [{"seconds": 1.0, "spp": 3, "image": half}]}));
        let error = read_checkpoints(Peer::Mitsuba, &report, &image(2, 2, 1.0)).unwrap_err();
        assert!(error.contains("4×2, the reference 2×2"), "{error}");
        std::fs::write(&report, "{").unwrap();
        assert!(read_checkpoints(Peer::Mitsuba, &report, &reference).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
