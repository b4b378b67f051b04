//! `include/lodestar.h` is what cbindgen generates from the crate now: a stale committed
//! header fails here. Regenerate with `LODESTAR_UPDATE_HEADER=1 cargo test -p
//! lodestar-capi --test header`.

use std::path::Path;

#[test]
fn committed_header_matches_the_generated_one() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml parses");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("the header is UTF-8");
    let committed_path = crate_dir.join("include/lodestar.h");
    if std::env::var_os("LODESTAR_UPDATE_HEADER").is_some() {
        std::fs::write(&committed_path, &generated).expect("include/lodestar.h is writable");
    }
    let committed = std::fs::read_to_string(&committed_path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/lodestar.h differs from what cbindgen generates now; regenerate it with \
         LODESTAR_UPDATE_HEADER=1 cargo test -p lodestar-capi --test header"
    );
}
