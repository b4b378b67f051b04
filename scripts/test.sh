#!/usr/bin/env bash
# The whole test suite, as CI runs it: set-up (with Embree 4 and a Vulkan driver for the
# GPU tracer, Mesa's lavapipe where there is no GPU), formatting, lints, docs, the no_std
# core build and its dependency list, every test of the workspace (Rust, C and C++ under
# valgrind, Embree against obvhs, the GPU tracer against the CPU one), the guided path
# tracer example (its guided mean against its unguided one), then a 30-second
# smoke run of each fuzz target. Prints each stage's time.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/setup.sh
scripts/provision-embree.sh
scripts/provision-vulkan.sh
# The GPU tests fail instead of skipping when no adapter is found.
export LODESTAR_REQUIRE_GPU=1
features=reference-tracer/embree,reference-tracer/gpu

stage() {
    local name=$1
    shift
    local start=$SECONDS
    echo "==> $name"
    "$@"
    echo "==> $name: $((SECONDS - start)) s"
}

core_dependencies_are_glam_and_libm() {
    cargo build -p guiding-core --no-default-features
    cargo build -p guiding-core --no-default-features --features hemisphere,lights,env,mixture,volume,tree,focal
    local dependencies
    dependencies=$(cargo tree -p guiding-core -e normal --prefix none --format '{p}' | awk '{print $1}' | sort -u | tr '\n' ' ')
    echo "guiding-core normal dependencies: $dependencies"
    [ "$dependencies" = "glam guiding-core libm " ] || { echo "guiding-core must depend on glam and libm only" >&2; return 1; }
}

total=$SECONDS
stage "format" cargo fmt --all -- --check
stage "format (fuzz)" cargo fmt --manifest-path fuzz/Cargo.toml -- --check
stage "clippy" cargo clippy --workspace --all-targets --features "$features" -- -D warnings
stage "docs" env RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --features "$features"
stage "no_std core" core_dependencies_are_glam_and_libm
stage "tests" cargo test --workspace --features "$features"
# The example a renderer author copies: it fails unless guided and unguided means agree.
stage "example" cargo run --profile test --example guided_path_tracer
stage "fuzz smoke" ./scripts/fuzz.sh "${LODESTAR_FUZZ_SECONDS:-30}"
echo "==> all stages passed in $((SECONDS - total)) s"
