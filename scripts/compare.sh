#!/usr/bin/env bash
# Error against time: renders each generated scene's reference once (out/references/,
# not committed), then runs every method for the same wall time and writes
# out/compare/<scene>/compare.{csv,md} and error.svg. The real scenes are measured
# against Tungsten's converged renders that ship with them.
#
#   door, cornell:   pt, nee, guided, guided-nee          (the directional guide)
#   window:          nee by luminance, nee with learned environment tiles, guided-nee with tiles
#   many_lights:     nee with uniform, power and learned light selection
#   caustic:         nee, guided-nee, bdpt, bdpt-guided    (reference by bdpt)
#   veach-ajar:      nee, guided, guided-nee              (pbrt-v3, 1280 × 720)
#   living-room:     nee by luminance and by tiles, guided and guided-nee with tiles (Mitsuba)
#   modern-hall:     nee with uniform, power and learned light selection (Mitsuba, at
#                    Tungsten's 1024 × 1024)
#
#   scripts/compare.sh [SECONDS] [REFERENCE_SPP] [SCENE…]   (defaults: 60 s, 2048 spp, all)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/setup.sh
# Embree is the faster intersector (--intersector auto picks it when built in).
scripts/provision-embree.sh
seconds=${1:-60}
reference_spp=${2:-2048}
shift $(( $# > 2 ? 2 : $# ))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(door cornell window many_lights caustic veach-ajar living-room modern-hall)
cargo build --release -p reference-tracer --features embree
lodestar=./target/release/lodestar
mkdir -p out/references
for scene in "${scenes[@]}"; do
    # Each reference uses an unbiased method that converges fast on its scene.
    file=scenes/$scene/scene.json
    extra=()
    reference=out/references/$scene-$reference_spp.exr
    case $scene in
        window) methods=nee+luminance,nee+tiles,guided-nee+tiles; reference_args=(--env-sampling tiles) ;;
        many_lights) methods=nee:uniform,nee:power,nee:learned; reference_args=(--light-selection learned) ;;
        # Light reaches the diffuse surfaces through glass: only bidirectional methods converge.
        caustic) methods=nee,guided-nee,bdpt,bdpt-guided; reference_args=(--integrator bdpt) ;;
        veach-ajar) methods=nee,guided,guided-nee; file=scenes/$scene/scene.pbrt ;;
        living-room) methods=nee+luminance,nee+tiles,guided+tiles,guided-nee+tiles; file=scenes/$scene/scene.xml ;;
        modern-hall)
            methods=nee:uniform,nee:power,nee:learned; file=scenes/$scene/scene.xml
            # Tungsten rendered it square; the scene's field of view runs along x.
            extra=(--resolution 1024x1024)
            ;;
        *) methods=pt,nee,guided,guided-nee; reference_args=(--integrator guided-nee) ;;
    esac
    case $scene in
        veach-ajar | living-room | modern-hall) reference=scenes/$scene/TungstenRender.exr ;;
        *)
            if [ ! -f "$reference" ]; then
                "$lodestar" reference "$file" "${reference_args[@]}" --spp "$reference_spp" --out "$reference"
            fi
            ;;
    esac
    "$lodestar" compare "$file" --methods "$methods" "${extra[@]}" \
        --seconds "$seconds" --reference "$reference" --out "out/compare/$scene"
done
