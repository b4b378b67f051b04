//! The Mitsuba peer (scripts/peer-mitsuba.sh) renders what Lodestar renders. These tests
//! run where the peer's virtual environment exists (the script installs it; the test
//! command does not, as it is a large download); elsewhere they say so and pass.

mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use reference_tracer::integrator::Method;
use reference_tracer::output::{read_image, Image};
use support::{render_image, repository_scene, settings};

/// The peer's Python, if its virtual environment is there.
fn peer_python() -> Option<PathBuf> {
    let python = repository().join(".cache/mitsuba-venv/bin/python");
    if python.exists() {
        Some(python)
    } else {
        eprintln!("skipped: no Mitsuba environment at {} (scripts/peer-mitsuba.sh makes it)", python.display());
        None
    }
}

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn run_peer(python: &Path, scene: &Path, seconds: &str, out: &Path) -> Output {
    Command::new(python)
        .arg(repository().join("scripts/peer_mitsuba.py"))
        .arg(scene)
        .arg(seconds)
        .arg(out)
        .output()
        .unwrap()
}

/// Mean of the pixels in columns `columns` of `image`.
fn mean_of_columns(image: &Image, columns: std::ops::Range<usize>) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for row in 0..image.height {
        for column in columns.clone() {
            sum += image.pixels[row * image.width + column];
        }
    }
    sum / (image.height * columns.len()) as f32
}

#[test]
fn the_mitsuba_peer_renders_cornell_as_lodestar_does() {
    let Some(python) = peer_python() else { return };
    let scene = repository_scene("cornell", 32, 32);
    let out = scene.with_file_name("peer.exr");
    let output = run_peer(&python, &scene, "4", &out);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let peer = read_image(&out).unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("json")).unwrap()).unwrap();
    assert!(report["spp"].as_u64().unwrap() > 0, "{report}");
    assert_eq!((peer.width, peer.height), (32, 32));
    let (ours, _) = render_image(&scene, settings(Method::Nee), None, 1024, 3);
    // The left half holds the red wall, the right half the green one: a mirrored or
    // rotated camera, a wrong light or a one-sided material moves these means by far
    // more than the 3 % both renders' noise allows.
    for (label, columns) in [("left half", 0..16), ("right half", 16..32), ("whole", 0..32)] {
        let (a, b) = (mean_of_columns(&peer, columns.clone()), mean_of_columns(&ours, columns));
        let relative = ((a - b).abs() / b).max_element();
        assert!(relative < 0.03, "{label}: Mitsuba {a} against Lodestar {b}");
    }
}

/// An OBJ whose faces take their MTL file's materials (McGuire's original Cornell box,
/// eight of them) reaches the peer written inline, as `compare --peer` writes it, and
/// the peer renders it as Lodestar renders the original.
#[test]
fn the_mitsuba_peer_renders_mtl_materials_written_inline() {
    let Some(python) = peer_python() else { return };
    let scene = repository_scene("cornell-box-original", 32, 32);
    let inline = scene.with_file_name("inline.json");
    reference_tracer::import::write_self_contained_json(&scene, &inline).unwrap();
    let out = scene.with_file_name("peer.exr");
    let output = run_peer(&python, &inline, "4", &out);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let peer = read_image(&out).unwrap();
    let (ours, _) = render_image(&scene, settings(Method::Nee), None, 1024, 3);
    for (label, columns) in [("left half", 0..16), ("right half", 16..32), ("whole", 0..32)] {
        let (a, b) = (mean_of_columns(&peer, columns.clone()), mean_of_columns(&ours, columns));
        let relative = ((a - b).abs() / b).max_element();
        assert!(relative < 0.03, "{label}: Mitsuba {a} against Lodestar {b}");
    }
}

#[test]
fn the_mitsuba_peer_refuses_what_it_cannot_render_alike_by_name() {
    let Some(python) = peer_python() else { return };
    let window = repository().join("scenes/window/scene.json");
    let output = run_peer(&python, &window, "1", &std::env::temp_dir().join("lodestar-peer-refused.exr"));
    assert_eq!(output.status.code(), Some(2));
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(message.contains("environment.type: 'image'"), "{message}");
    let output = run_peer(&python, &repository().join("scenes/living-room/scene.xml"), "1", Path::new("unused.exr"));
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("lodestar convert"));
    // A shape without a material of its own is refused by name, not by a traceback.
    let original = repository().join("scenes/cornell-box-original/scene.json");
    let output = run_peer(&python, &original, "1", Path::new("unused.exr"));
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("shapes[0]: a shape without 'material'"));
}

/// Runs `lodestar compare` on cornell 16² against a flat reference with `--peer mitsuba`
/// and the peer script `script` (None: the repository's), writing into `out`.
fn compare_with_peer(script: Option<&Path>, out: &Path, methods: &str, seconds: &str) -> Output {
    let scene = repository_scene("cornell", 16, 16);
    let reference = scene.with_file_name("flat.exr");
    let flat = Image { width: 16, height: 16, pixels: vec![Vec3::splat(0.2); 256] };
    reference_tracer::output::write_exr(&reference, &flat).unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_lodestar"));
    command.args(["compare", scene.to_str().unwrap(), "--methods", methods, "--seconds", seconds]);
    command.args(["--reference", reference.to_str().unwrap(), "--out", out.to_str().unwrap(), "--peer", "mitsuba"]);
    if let Some(script) = script {
        command.env("LODESTAR_PEER_MITSUBA", script);
    }
    command.output().unwrap()
}

/// Runs everywhere: a peer that refuses the scene (status 2, the feature named) or a
/// script that is not there stops `compare` before it renders anything, with the
/// peer's own message.
#[test]
fn compare_stops_with_the_peers_refusal_named() {
    let folder = std::env::temp_dir().join(format!("lodestar-peer-refusal-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();
    let script = folder.join("refuse.sh");
    std::fs::write(&script, "echo \"peer-mitsuba: $1: textures are not supported by the Mitsuba peer\" >&2\nexit 2\n")
        .unwrap();
    let output = compare_with_peer(Some(&script), &folder.join("out"), "nee", "1");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("--peer mitsuba: refused the scene") && stderr.contains("textures are not supported"),
        "{stderr}"
    );
    assert!(!stderr.contains("nee: rendering"), "rendered before the peer: {stderr}");
    let output = compare_with_peer(Some(&folder.join("missing.sh")), &folder.join("out"), "nee", "1");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && stderr.contains("no script at"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    std::fs::remove_dir_all(&folder).unwrap();
}

/// Where the venv exists: the peer is a row of the table and of compare.csv, with its
/// checkpoints (about 1 s and the last) measured against the same reference.
#[test]
fn compare_adds_the_mitsuba_peer_as_a_row() {
    let Some(_) = peer_python() else { return };
    let out = std::env::temp_dir().join(format!("lodestar-peer-compare-{}", std::process::id()));
    let output = compare_with_peer(None, &out, "nee", "3");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let table = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(table.contains("| mitsuba |") && table.contains("| nee |"), "{table}");
    let csv = std::fs::read_to_string(out.join("compare.csv")).unwrap();
    let peer_rows: Vec<Vec<f64>> = csv
        .lines()
        .filter(|l| l.starts_with("mitsuba,"))
        .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(!peer_rows.is_empty(), "{csv}");
    // seconds, spp, paths/s positive; relMSE finite and of a flat 0.2 image against
    // cornell's: far from 0.
    for row in &peer_rows {
        assert!(row[0] > 0.0 && row[1] >= 1.0 && row[2] > 0.0, "{row:?}");
        assert!(row[5].is_finite() && row[5] > 1e-3, "{row:?}");
    }
    std::fs::remove_dir_all(&out).unwrap();
}
