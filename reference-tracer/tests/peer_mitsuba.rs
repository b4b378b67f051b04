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
}
