#!/usr/bin/env bash
# Error against time on the door and Cornell scenes: renders each scene's reference once
# (out/references/, not committed), then runs every method for the same wall time and
# writes out/compare/<scene>/compare.{csv,md} and error.svg.
#
#   scripts/compare.sh [SECONDS] [REFERENCE_SPP]     (defaults: 60 s, 2048 spp)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/setup.sh
seconds=${1:-60}
reference_spp=${2:-2048}
cargo build --release -p reference-tracer
lodestar=./target/release/lodestar
mkdir -p out/references
for scene in door cornell; do
    reference=out/references/$scene-$reference_spp.exr
    if [ ! -f "$reference" ]; then
        # guided-nee is unbiased and converges fastest on both scenes.
        "$lodestar" reference "scenes/$scene/scene.json" --integrator guided-nee --spp "$reference_spp" --out "$reference"
    fi
    "$lodestar" compare "scenes/$scene/scene.json" --methods pt,nee,guided,guided-nee \
        --seconds "$seconds" --reference "$reference" --out "out/compare/$scene"
done
