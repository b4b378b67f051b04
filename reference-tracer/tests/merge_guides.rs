//! `render --save-guide`, `merge-guides` and `render --load-guide` from the command line:
//! two processes learn cornell with different seeds, their guides merge into one that
//! holds every update of both, and a render starts from it. (That the merge of two grids
//! equals the grid that learned everything is guiding-core's own test.)

mod support;

use std::path::Path;
use std::process::Command;

fn lodestar(args: &[&str]) -> String {
    let output = Command::new(env!("CARGO_BIN_EXE_lodestar")).args(args).output().expect("lodestar runs");
    let text = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "lodestar {args:?} failed:\n{text}");
    text
}

/// The accepted updates a merged guide reports.
fn merged_updates(text: &str) -> u64 {
    text.split("guides: ").nth(1).and_then(|rest| rest.split(' ').next()).and_then(|n| n.parse().ok()).unwrap()
}

fn accepted_updates(guide: &Path) -> u64 {
    let bytes = std::fs::read(guide).unwrap();
    let grid = <guiding_core::HemisphereGrid as guiding_core::Guide>::from_bytes(&bytes).unwrap();
    guiding_core::Guide::stats(&grid).accepted_updates
}

#[test]
fn guides_learned_apart_merge_and_serve_a_render() {
    let scene = support::repository_scene("cornell", 24, 24);
    let folder = support::temp_folder("merge-guides");
    let path = |name: &str| folder.join(name).display().to_string();
    for seed in ["1", "2"] {
        let (out, guide) = (path(&format!("part{seed}.exr")), path(&format!("part{seed}.guide")));
        let scene = scene.display().to_string();
        lodestar(&[
            "render",
            &scene,
            "--spp",
            "8",
            "--seed",
            seed,
            "--threads",
            "1",
            "--out",
            &out,
            "--save-guide",
            &guide,
        ]);
    }
    let (first, second) =
        (accepted_updates(Path::new(&path("part1.guide"))), accepted_updates(Path::new(&path("part2.guide"))));
    assert!(first > 0 && second > 0);
    let text = lodestar(&["merge-guides", &path("part1.guide"), &path("part2.guide"), "--out", &path("merged.guide")]);
    assert_eq!(merged_updates(&text), first + second, "{text}");
    assert_eq!(accepted_updates(Path::new(&path("merged.guide"))), first + second);
    let scene = scene.display().to_string();
    lodestar(&["render", &scene, "--spp", "2", "--out", &path("again.exr"), "--load-guide", &path("merged.guide")]);

    // A damaged guide is refused with its file named; so is merging into another structure.
    std::fs::write(path("broken.guide"), b"not a guide").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_lodestar"))
        .args(["merge-guides", &path("part1.guide"), &path("broken.guide"), "--out", &path("x.guide")])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && text.contains("broken.guide"), "{text}");
    let output = Command::new(env!("CARGO_BIN_EXE_lodestar"))
        .args([
            "merge-guides",
            &path("part1.guide"),
            &path("part2.guide"),
            "--guide",
            "tree",
            "--out",
            &path("x.guide"),
        ])
        .output()
        .unwrap();
    assert!(!output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
}
