//! Builds the C error-path test (`tests/c/api_errors.c`) and the C++ example
//! (`examples/cpp/minimal_renderer.cpp`) with the system's gcc and g++ against the
//! `liblodestar.so` cargo built beside this test, runs them, and runs both again under
//! valgrind's memcheck (errors and definite leaks fail). `scripts/setup.sh` installs
//! g++ and valgrind.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The directory holding a freshly built `liblodestar.so`. Cargo builds only the rlib
/// flavour of a package for its tests, so the test builds the C library itself, with
/// the cargo that runs it, into the same target directory.
fn library_dir() -> PathBuf {
    static BUILT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| {
            let exe = std::env::current_exe().expect("the test binary's path");
            let target = exe.ancestors().nth(3).expect("target/<profile>/deps/<test>").to_path_buf();
            let status = Command::new(env!("CARGO"))
                .args(["build", "--release", "-p", "lodestar-capi", "--target-dir"])
                .arg(&target)
                .status()
                .expect("cargo runs");
            assert!(status.success(), "cargo build -p lodestar-capi failed");
            target.join("release")
        })
        .clone()
}

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Compiles `source` with `compiler` and `flags` into the test's scratch directory.
fn compile(compiler: &str, source: &str, flags: &[&str], output: &str) -> PathBuf {
    let library = library_dir();
    let binary = Path::new(env!("CARGO_TARGET_TMPDIR")).join(output);
    let status = Command::new(compiler)
        .args(flags)
        .arg(crate_dir().join(source))
        .arg("-I")
        .arg(crate_dir().join("include"))
        .arg("-L")
        .arg(&library)
        .arg(format!("-Wl,-rpath,{}", library.display()))
        .args(["-llodestar", "-pthread", "-lm", "-o"])
        .arg(&binary)
        .status()
        .unwrap_or_else(|e| panic!("cannot run {compiler} ({e}): run scripts/setup.sh to install it"));
    assert!(status.success(), "{compiler} could not build {source}");
    binary
}

/// Runs a program (optionally under valgrind), returning its stdout; fails on a
/// non-zero exit with everything it printed.
fn run(program: &Path, args: &[&str], under_valgrind: bool) -> String {
    let mut command = if under_valgrind {
        let mut c = Command::new("valgrind");
        c.args(["-q", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=definite"]).arg(program);
        c
    } else {
        Command::new(program)
    };
    let output = command
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {} ({e}): run scripts/setup.sh for valgrind", program.display()));
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success(),
        "{} failed ({}){}:\n{stdout}\n{}",
        program.display(),
        output.status,
        if under_valgrind { " under valgrind" } else { "" },
        String::from_utf8_lossy(&output.stderr)
    );
    stdout
}

#[test]
fn c_error_paths_pass_and_run_clean_under_valgrind() {
    let binary =
        compile("gcc", "tests/c/api_errors.c", &["-std=c11", "-O1", "-Wall", "-Wextra", "-Werror"], "api_errors");
    for valgrind in [false, true] {
        let out = run(&binary, &[], valgrind);
        let summary = out.lines().last().unwrap_or_default();
        let (passed, total) = summary
            .strip_prefix("api_errors: ")
            .and_then(|rest| rest.strip_suffix(" checks passed"))
            .and_then(|rest| rest.split_once(" of "))
            .unwrap_or_else(|| panic!("unexpected output:\n{out}"));
        assert_eq!(passed, total, "{out}");
        assert!(total.parse::<u32>().unwrap() >= 100, "{out}");
    }
}

#[test]
fn cpp_example_renders_learns_reloads_and_runs_clean_under_valgrind() {
    let binary = compile(
        "g++",
        "examples/cpp/minimal_renderer.cpp",
        &["-std=c++17", "-O2", "-Wall", "-Wextra", "-Werror"],
        "minimal_renderer",
    );
    for (passes, valgrind) in [("16", false), ("4", true)] {
        let out = run(&binary, &[passes], valgrind);
        let mean = |label: &str| -> f64 {
            out.lines()
                .find_map(|line| line.strip_prefix(label))
                .and_then(|rest| rest.split_whitespace().next())
                .and_then(|value| value.parse().ok())
                .unwrap_or_else(|| panic!("no `{label}` line in:\n{out}"))
        };
        let (unguided, guided, reloaded) = (mean("unguided mean "), mean("guided mean "), mean("reloaded mean "));
        assert!(unguided > 0.05 && guided > 0.05 && reloaded > 0.05, "{out}");
        assert!(out.contains("reloaded guide: 0 of "), "{out}");
        assert!(out.trim_end().ends_with("means agree"), "{out}");
    }
}
