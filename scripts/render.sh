#!/usr/bin/env bash
# Renders the default scene (the Cornell box) guided, after setting up the machine:
# writes out/cornell.exr, out/cornell.png and out/cornell.json. Extra arguments go to
# `lodestar render` (e.g. --integrator nee --spp 256).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/setup.sh
# Embree is the faster intersector (--intersector auto picks it when built in).
scripts/provision-embree.sh
cargo build --release -p reference-tracer --features embree
./target/release/lodestar render scenes/cornell/scene.json --integrator guided-nee --spp 128 --out out/cornell.exr "$@"
