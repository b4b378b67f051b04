//! Finds Embree 4: `EMBREE4_LIB_DIR` if set, else pkg-config `embree4` (Debian 13+), else
//! what `scripts/provision-embree.sh` unpacked into `.cache/embree4/lib` of the
//! workspace. A library outside the system paths is linked through links to it in
//! OUT_DIR, a search path inside `target/` that `cargo test` and `cargo run` put on
//! LD_LIBRARY_PATH. Nothing is downloaded here.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-env-changed=EMBREE4_LIB_DIR");
    println!("cargo:rerun-if-env-changed=LODESTAR_EMBREE_DIR");
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let provisioned = std::env::var("LODESTAR_EMBREE_DIR")
        .map(|d| PathBuf::from(d).join("lib"))
        .unwrap_or_else(|_| manifest.join("../../.cache/embree4/lib"));
    println!("cargo:rerun-if-changed={}", provisioned.display());

    if let Ok(dir) = std::env::var("EMBREE4_LIB_DIR") {
        link_from(Path::new(&dir));
    } else if let Some(dir) = pkg_config_lib_dir() {
        println!("cargo:rustc-link-search=native={dir}");
        println!("cargo:rustc-link-lib=dylib=embree4");
        println!("cargo:lib_dir={dir}");
    } else if provisioned.join("libembree4.so").exists() {
        link_from(&provisioned);
    } else {
        panic!(
            "guiding-embree: Embree 4 not found. Run scripts/provision-embree.sh (Debian 12: unpacks \
             Embree 4.4 into .cache/embree4), install libembree-dev on Debian 13+, or set \
             EMBREE4_LIB_DIR to a folder holding libembree4.so."
        );
    }
}

fn pkg_config_lib_dir() -> Option<String> {
    let output = Command::new("pkg-config").args(["--libs-only-L", "embree4"]).output().ok()?;
    if !output.status.success() {
        return None;
    }
    let flags = String::from_utf8(output.stdout).ok()?;
    // An empty -L list means a system folder the linker searches anyway.
    Some(flags.split_whitespace().find_map(|f| f.strip_prefix("-L")).unwrap_or("/usr/lib").to_string())
}

/// Links every file of `dir` into OUT_DIR/lib and links against libembree4 there.
fn link_from(dir: &Path) {
    let dir = dir.canonicalize().unwrap_or_else(|e| panic!("guiding-embree: {}: {e}", dir.display()));
    let local = PathBuf::from(std::env::var("OUT_DIR").unwrap()).join("lib");
    std::fs::create_dir_all(&local).unwrap();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name();
        if !name.to_string_lossy().contains(".so") {
            continue;
        }
        let link = local.join(&name);
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(entry.path(), &link).unwrap();
    }
    assert!(local.join("libembree4.so").exists(), "guiding-embree: {} holds no libembree4.so", dir.display());
    println!("cargo:rustc-link-search=native={}", local.display());
    println!("cargo:rustc-link-lib=dylib=embree4");
    println!("cargo:lib_dir={}", local.display());
}
