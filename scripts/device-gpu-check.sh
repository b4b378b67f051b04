#!/usr/bin/env bash
# Prepares the GPU tracer's check on a machine with a real GPU but no Rust toolchain and no
# network (the device machine: DEVELOPERS.md). Run here, it builds (x86-64, release) the
# `lodestar` binary with the `gpu` feature and the GPU agreement test binary, renders the
# CPU references the check needs (once; kept in .cache/references), downloads the Vulkan
# loader packages, and copies all of it with the scenes into .device-gpu/ (ignored by
# git). It ends by printing the one command to run there, from the repository root:
#
#     bash .device-gpu/run.sh
#
# which prints the adapter wgpu picked (and fails if it is a software one, unless
# LODESTAR_ALLOW_SOFTWARE=1), runs the GPU agreement tests with LODESTAR_REQUIRE_GPU=1,
# and runs `lodestar compare --methods nee,gpu:nee,guided-nee,gpu:guided-nee,gpu:guided-nee@tree`
# on door and cornell at their resolution and at 1280×720, writing summary.md, log.txt and
# results.tar.gz into $OUT (or .device-gpu/out). See `run.sh`'s head for its settings.
#
# To try it end to end on lavapipe (this machine, no GPU):
#
#     REFERENCE_SPP=16 ./scripts/device-gpu-check.sh && LODESTAR_ALLOW_SOFTWARE=1 \
#         SECONDS_PER_METHOD=2 REFERENCE_SECONDS=4 HD=160x90 bash .device-gpu/run.sh
set -euo pipefail
cd "$(dirname "$0")/.."

./scripts/setup.sh
./scripts/provision-vulkan.sh
# shellcheck disable=SC1091
source "$HOME/.cargo/env" 2>/dev/null || true

bundle=.device-gpu
rm -rf "$bundle"
mkdir -p "$bundle/bin" "$bundle/scenes" "$bundle/references" "$bundle/gl"

echo "device-gpu-check: building lodestar (release, gpu) and the GPU agreement tests"
cargo build --release --locked -p reference-tracer --features gpu --bin lodestar
cp target/release/lodestar "$bundle/bin/"
tests=$(cargo test --release --locked -p reference-tracer --features gpu --test gpu_agreement --no-run \
    --message-format=json 2>/dev/null |
    python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "gpu_agreement" and m.get("executable"):
        print(m["executable"])')
cp "$tests" "$bundle/bin/gpu_agreement"

# The references at the scenes' own resolution: REFERENCE_SPP (8192) spp of CPU nee,
# rendered here once (minutes on two cores) and kept. The 1280×720 ones are rendered
# there by the GPU, whose nee the agreement tests check against the CPU's.
spp=${REFERENCE_SPP:-8192}
mkdir -p .cache/references
for scene in door cornell; do
    reference=.cache/references/$scene-native-$spp.exr
    if [ ! -f "$reference" ]; then
        echo "device-gpu-check: rendering the $scene reference ($spp spp, once)"
        target/release/lodestar reference "scenes/$scene/scene.json" --spp "$spp" --out "$reference"
    fi
    cp "$reference" "$bundle/references/$scene-native.exr"
done
# The scenes the compare and the agreement tests render.
for scene in door cornell window envmaps; do
    cp -r "scenes/$scene" "$bundle/scenes/"
done

# The Vulkan loader and GL dispatch libraries the device machine lacks (it has NVIDIA's
# driver but not the loader): unpacked there at the start of each run.
echo "device-gpu-check: downloading the Vulkan loader packages"
lists=$(mktemp -d)
mkdir -p "$lists/partial"
apt=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::State::Lists=$lists")
apt-get "${apt[@]}" update -qq >/dev/null 2>&1 || true
(cd "$bundle/gl" && apt-get "${apt[@]}" download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2 >/dev/null)
rm -rf "$lists"

cp scripts/device-gpu-run.sh "$bundle/run.sh"
echo "device-gpu-check: $(du -sh "$bundle" | cut -f1) in $bundle; run there, from the repository root:"
echo
echo "    bash $bundle/run.sh"
echo
echo "(device tool: carry [\"$bundle\"], timeout_s 600)"
