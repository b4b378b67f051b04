#!/usr/bin/env bash
# Error against time: renders each scene's reference once (out/references/, not
# committed), then runs every method for the same wall time and writes
# out/compare/<scene>/compare.{csv,md} and error.svg.
#
#   door, cornell:   pt, nee, guided, guided-nee          (the directional guide)
#   window:          nee by luminance, nee with learned environment tiles, guided-nee with tiles
#   many_lights:     nee with uniform, power and learned light selection
#
#   scripts/compare.sh [SECONDS] [REFERENCE_SPP] [SCENE…]   (defaults: 60 s, 2048 spp, all four)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/setup.sh
seconds=${1:-60}
reference_spp=${2:-2048}
shift $(( $# > 2 ? 2 : $# ))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(door cornell window many_lights)
cargo build --release -p reference-tracer
lodestar=./target/release/lodestar
mkdir -p out/references
for scene in "${scenes[@]}"; do
    # Each reference uses an unbiased method that converges fast on its scene.
    case $scene in
        window) methods=nee+luminance,nee+tiles,guided-nee+tiles; reference_args=(--env-sampling tiles) ;;
        many_lights) methods=nee:uniform,nee:power,nee:learned; reference_args=(--light-selection learned) ;;
        *) methods=pt,nee,guided,guided-nee; reference_args=(--integrator guided-nee) ;;
    esac
    reference=out/references/$scene-$reference_spp.exr
    if [ ! -f "$reference" ]; then
        "$lodestar" reference "scenes/$scene/scene.json" "${reference_args[@]}" --spp "$reference_spp" --out "$reference"
    fi
    "$lodestar" compare "scenes/$scene/scene.json" --methods "$methods" \
        --seconds "$seconds" --reference "$reference" --out "out/compare/$scene"
done
