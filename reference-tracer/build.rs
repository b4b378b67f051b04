//! With the `embree` feature, gives the `lodestar` binary an rpath to the Embree library
//! guiding-embree linked (DEP_EMBREE4_LIB_DIR), so it runs outside `cargo run` too.

fn main() {
    println!("cargo:rerun-if-env-changed=DEP_EMBREE4_LIB_DIR");
    if let Ok(dir) = std::env::var("DEP_EMBREE4_LIB_DIR") {
        println!("cargo:rustc-link-arg-bins=-Wl,-rpath,{dir}");
    }
}
