//! Installs liblodestar into a scratch prefix with `scripts/install-capi.sh`, builds the
//! C error-path test (`tests/c/api_errors.c`) and the C++ example
//! (`examples/cpp/minimal_renderer.cpp`, through `lodestar.hpp`) with the system's gcc and
//! g++ from `pkg-config --cflags --libs lodestar`, runs them, and runs both again under
//! valgrind's memcheck (errors and definite leaks fail). `scripts/setup.sh` installs
//! g++, pkg-config and valgrind.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The prefix `scripts/install-capi.sh` installed a freshly built liblodestar into (its
/// headers, `lodestar.pc` and CMake config beside it). Cargo builds only the rlib flavour
/// of a package for its tests, so the script builds the C library itself, with the cargo
/// that runs this test, into the same target directory.
fn install_prefix() -> PathBuf {
    static INSTALLED: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    INSTALLED
        .get_or_init(|| {
            let exe = std::env::current_exe().expect("the test binary's path");
            let target = exe.ancestors().nth(3).expect("target/<profile>/deps/<test>").to_path_buf();
            let prefix = Path::new(env!("CARGO_TARGET_TMPDIR")).join("lodestar-prefix");
            let script = crate_dir().join("../../scripts/install-capi.sh");
            let cargo_dir = Path::new(env!("CARGO")).parent().expect("cargo's folder").to_path_buf();
            let path = std::env::join_paths(
                std::iter::once(cargo_dir).chain(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())),
            )
            .expect("PATH joins");
            let status = Command::new("bash")
                .arg(script)
                .arg(&prefix)
                .env("CARGO_TARGET_DIR", &target)
                .env("PATH", path)
                .status()
                .expect("bash runs");
            assert!(status.success(), "scripts/install-capi.sh failed");
            for installed in ["lib/liblodestar.so", "lib/liblodestar.a", "include/lodestar.h", "include/lodestar.hpp"] {
                assert!(prefix.join(installed).is_file(), "{installed} was not installed");
            }
            assert!(prefix.join("lib/cmake/lodestar/lodestarConfig.cmake").is_file());
            prefix
        })
        .clone()
}

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `pkg-config` with `args` for the installed lodestar, split into compiler arguments.
fn pkg_config(args: &[&str]) -> Vec<String> {
    let output = Command::new("pkg-config")
        .args(args)
        .arg("lodestar")
        .env("PKG_CONFIG_PATH", install_prefix().join("lib/pkgconfig"))
        .output()
        .expect("pkg-config runs (scripts/setup.sh installs it)");
    assert!(output.status.success(), "pkg-config {args:?} lodestar: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).expect("UTF-8").split_whitespace().map(str::to_owned).collect()
}

/// Compiles `source` with `compiler` and `flags` into the test's scratch directory,
/// against the installed library as `pkg-config --cflags --libs lodestar` describes it.
fn compile(compiler: &str, source: &str, flags: &[&str], output: &str) -> PathBuf {
    let binary = Path::new(env!("CARGO_TARGET_TMPDIR")).join(output);
    let status = Command::new(compiler)
        .args(flags)
        .arg(crate_dir().join(source))
        .args(pkg_config(&["--cflags", "--libs"]))
        .args(["-pthread", "-lm", "-o"])
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
    // Cargo's LD_LIBRARY_PATH (target/debug/deps first) may hold an older liblodestar.so
    // from a debug build; the program must load the installed one its rpath names.
    let output = command
        .args(args)
        .env_remove("LD_LIBRARY_PATH")
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
fn cpp_wrapper_without_exceptions_returns_statuses_and_runs_clean_under_valgrind() {
    let binary = compile(
        "g++",
        "tests/cpp/status_only.cpp",
        &["-std=c++17", "-O1", "-fno-exceptions", "-Wall", "-Wextra", "-Werror"],
        "status_only",
    );
    for valgrind in [false, true] {
        let out = run(&binary, &[], valgrind);
        let summary = out.lines().last().unwrap_or_default();
        let (passed, total) = summary
            .strip_prefix("status_only: ")
            .and_then(|rest| rest.strip_suffix(" checks passed"))
            .and_then(|rest| rest.split_once(" of "))
            .unwrap_or_else(|| panic!("unexpected output:\n{out}"));
        assert_eq!(passed, total, "{out}");
        assert!(total.parse::<u32>().unwrap() >= 60, "{out}");
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

#[test]
fn cmake_finds_the_installed_library_and_builds_the_example() {
    let build = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cmake-example");
    let _ = std::fs::remove_dir_all(&build);
    let cmake = |args: &[&std::ffi::OsStr]| {
        let output = Command::new("cmake")
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("cannot run cmake ({e}): run scripts/setup.sh to install it"));
        let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
        assert!(output.status.success(), "cmake {args:?} failed:\n{text}");
    };
    let prefix = format!("-DCMAKE_PREFIX_PATH={}", install_prefix().display());
    let source = crate_dir().join("examples/cpp");
    cmake(&["-S".as_ref(), source.as_os_str(), "-B".as_ref(), build.as_os_str(), prefix.as_ref()]);
    cmake(&["--build".as_ref(), build.as_os_str()]);
    let out = run(&build.join("minimal_renderer"), &["4"], false);
    assert!(out.trim_end().ends_with("means agree"), "{out}");
}
