//! `render --save-guide`, `merge-guides` and `render --load-guide` from the command line,
//! for every guide that merges: two processes learn a scene with different seeds, their
//! guides merge into one that holds every update of both, and a render starts from it.
//! (That the merges are exact, or what they approximate, is guiding-core's own test.)

mod support;

use std::path::Path;
use std::process::Command;

use guiding_core::{EnvTileGuide, Guide, LightGuide, SpatialDirectionalTree};

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
    let grid = guiding_core::HemisphereGrid::from_bytes(&bytes).unwrap();
    grid.stats().accepted_updates
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

/// Renders `scene` with seeds 1 and 2 and `args`, each saving with `save_flag` into
/// `name1` and `name2` in `folder`; returns both paths.
fn learn_apart(scene: &Path, folder: &Path, args: &[&str], save_flag: &str, name: &str) -> [String; 2] {
    ["1", "2"].map(|seed| {
        let out = folder.join(format!("{name}{seed}.exr")).display().to_string();
        let saved = folder.join(format!("{name}{seed}.guide")).display().to_string();
        let scene = scene.display().to_string();
        let mut all = vec!["render", &scene, "--spp", "8", "--seed", seed, "--threads", "1", "--out", &out];
        all.extend_from_slice(args);
        all.extend_from_slice(&[save_flag, &saved]);
        lodestar(&all);
        saved
    })
}

#[test]
fn trees_volumes_and_mixtures_merge_from_the_command_line() {
    let scene = support::repository_scene("cornell", 24, 24);
    let folder = support::temp_folder("merge-trees");
    for structure in ["tree", "volume", "mixture"] {
        let [a, b] = learn_apart(&scene, &folder, &["--guide", structure], "--save-guide", structure);
        let merged = folder.join(format!("{structure}.merged")).display().to_string();
        let text = lodestar(&["merge-guides", &a, &b, "--guide", structure, "--out", &merged]);
        if structure == "tree" {
            let updates = |path: &str| {
                SpatialDirectionalTree::from_bytes(&std::fs::read(path).unwrap()).unwrap().stats().accepted_updates
            };
            let (first, second) = (updates(&a), updates(&b));
            assert!(first > 0 && second > 0);
            assert_eq!(merged_updates(&text), first + second, "{text}");
            assert_eq!(updates(&merged), first + second);
        }
        let scene = scene.display().to_string();
        let again = folder.join(format!("{structure}-again.exr")).display().to_string();
        lodestar(&["render", &scene, "--spp", "2", "--guide", structure, "--out", &again, "--load-guide", &merged]);
    }
}

#[test]
fn light_and_environment_guides_save_merge_and_load() {
    let folder = support::temp_folder("merge-lights");
    let path = |name: &str| folder.join(name).display().to_string();

    // Learned light selection on cornell, its light cut into parts to choose among.
    let cornell = support::repository_scene("cornell", 24, 24);
    let lights = ["--integrator", "nee", "--light-selection", "learned", "--light-split", "4"];
    let [a, b] = learn_apart(&cornell, &folder, &lights, "--save-light-guide", "lights");
    lodestar(&["merge-guides", &a, &b, "--guide", "lights", "--out", &path("lights.merged")]);
    // The file holds exactly the in-process merge of the two.
    let read = |p: &str| LightGuide::from_bytes(&std::fs::read(p).unwrap()).unwrap();
    let mut expected = read(&a);
    expected.merge(&read(&b)).unwrap();
    assert_eq!(std::fs::read(path("lights.merged")).unwrap(), expected.to_bytes());
    let cornell_text = cornell.display().to_string();
    let out = path("l.exr");
    let again = ["render", cornell_text.as_str(), "--spp", "2", "--out", out.as_str()];
    let merged_lights = path("lights.merged");
    let mut with_lights = again.to_vec();
    with_lights.extend_from_slice(&lights);
    with_lights.extend_from_slice(&["--load-light-guide", &merged_lights]);
    lodestar(&with_lights);
    // A render without learned selection has no light guide to load into.
    let mut without = again.to_vec();
    without.extend_from_slice(&[
        "--integrator",
        "nee",
        "--light-selection",
        "power",
        "--load-light-guide",
        &merged_lights,
    ]);
    let output = Command::new(env!("CARGO_BIN_EXE_lodestar")).args(&without).output().unwrap();
    let text = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && text.contains("no learned light selection"), "{text}");
    // A save the render cannot honour is refused before it renders: nothing is written.
    let refused = path("refused.exr");
    let guide_file = path("refused.guide");
    let missing_folder = folder.join("missing").join("lights.bin").display().to_string();
    let unguided = ["--integrator", "nee", "--save-guide", guide_file.as_str()];
    let nowhere = [&lights[..], &["--save-light-guide", missing_folder.as_str()]].concat();
    for (extra, expected) in [(&unguided[..], "no directional guide"), (&nowhere[..], "does not exist")] {
        let mut args = vec!["render", cornell_text.as_str(), "--spp", "2", "--out", refused.as_str()];
        args.extend_from_slice(extra);
        let output = Command::new(env!("CARGO_BIN_EXE_lodestar")).args(&args).output().unwrap();
        let text = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success() && text.contains(expected), "{text}");
        assert!(!Path::new(&refused).exists(), "rendered before refusing: {text}");
    }

    // Environment tiles on the window scene: the merge reads the guides against its map.
    let window = support::repository_scene("window", 24, 24);
    let tiles = ["--integrator", "nee", "--env-sampling", "tiles"];
    let [a, b] = learn_apart(&window, &folder, &tiles, "--save-env-guide", "env");
    let window_text = window.display().to_string();
    let merged_env = path("env.merged");
    let output = Command::new(env!("CARGO_BIN_EXE_lodestar"))
        .args(["merge-guides", &a, &b, "--guide", "environment", "--out", &merged_env])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && text.contains("needs --scene"), "{text}");
    lodestar(&["merge-guides", &a, &b, "--guide", "environment", "--scene", &window_text, "--out", &merged_env]);
    let scene = reference_tracer::scene::Scene::load(&window).unwrap();
    let environment = scene.environment.as_ref().unwrap();
    let (width, height, luminance) = environment.sky.luminance_grid();
    let map = guiding_core::environment::EnvironmentTiles::new(width, height, &luminance, [32, 16]).unwrap();
    let sun = environment.sun.map(|sun| sun.disk);
    let read = |p: &str| EnvTileGuide::from_bytes(&std::fs::read(p).unwrap(), map.clone(), sun).unwrap();
    let mut expected = read(&a);
    expected.merge(&read(&b)).unwrap();
    assert_eq!(std::fs::read(&merged_env).unwrap(), expected.to_bytes());
    let out = path("e.exr");
    let mut load = vec!["render", &window_text, "--spp", "2", "--out", &out, "--load-env-guide", &merged_env];
    load.extend_from_slice(&tiles);
    lodestar(&load);
}
