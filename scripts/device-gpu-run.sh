#!/usr/bin/env bash
# The GPU check itself, run on the machine with the GPU from the bundle that
# scripts/device-gpu-check.sh prepares (copied there as .device-gpu/run.sh; it finds
# everything beside itself, so it runs from any folder). Needs no Rust and no network.
#
# Settings (environment):
#   OUT                  where summary.md, log.txt and results.tar.gz go (default: out/ beside this)
#   SECONDS_PER_METHOD   each compare row's wall time (default 16: five rows on four
#                        images, the whole run about 8 minutes on the device, inside its
#                        10-minute limit)
#   REFERENCE_SECONDS    the GPU's nee render that serves as the 1280×720 reference (default 60)
#   HD                   the large resolution (default 1280x720)
#   LODESTAR_ALLOW_SOFTWARE=1  accept a software adapter (lavapipe), to try the bundle here
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${OUT:-$here/out}
seconds=${SECONDS_PER_METHOD:-16}
reference_seconds=${REFERENCE_SECONDS:-60}
hd=${HD:-1280x720}
work=$(mktemp -d)
mkdir -p "$out"
log=$out/log.txt
summary=$out/summary.md
: >"$log"
say() { echo "$*" | tee -a "$log"; }

# The Vulkan loader: unpacked from the bundle where the machine has none (as root only:
# it writes under /).
if ! ldconfig -p 2>/dev/null | grep -q libvulkan.so.1; then
    if [ "$(id -u)" = 0 ] && compgen -G "$here/gl/*.deb" >/dev/null; then
        for package in "$here"/gl/*.deb; do dpkg -x "$package" /; done
        ldconfig
        say "loader: unpacked $(ls "$here"/gl/*.deb | wc -l) packages"
    else
        say "loader: none installed and none unpacked (not root, or no packages in the bundle)"
    fi
fi
# NVIDIA's container images keep the driver's ICD outside the loader's search path.
nvidia_icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -f "$nvidia_icd" ]; then
    export VK_DRIVER_FILES=$nvidia_icd
fi

# Vulkan's window-system layers complain on every start without one.
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
    XDG_RUNTIME_DIR=$(mktemp -d)
    export XDG_RUNTIME_DIR
fi

lodestar=$here/bin/lodestar
{
    echo "# GPU check, $(date -u +%Y-%m-%dT%H:%MZ)"
    echo
    echo "- machine: $(nproc) cores, $(uname -m); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo 'no nvidia-smi')"
    echo "- settings: ${seconds} s per method, ${reference_seconds} s GPU nee references at $hd"
} >"$summary"

# 1. The adapter, and the agreement tests that must find it.
say "== GPU agreement tests (LODESTAR_REQUIRE_GPU=1)"
LODESTAR_REQUIRE_GPU=1 LODESTAR_SCENES="$here/scenes" "$here/bin/gpu_agreement" --test-threads=1 --nocapture 2>&1 | tee -a "$log"
tests=${PIPESTATUS[0]}
# `lodestar` and the tests print the adapter as "gpu: NAME, TYPE".
adapter=$(sed -n 's/^gpu: //p' "$log" | head -n 1)
software=no
case "$adapter" in *llvmpipe* | *", Cpu") software=yes ;; esac
{
    echo "- adapter: ${adapter:-none found}"
    echo "- agreement tests: $([ "$tests" = 0 ] && echo passed || echo "FAILED (exit $tests)")"
} >>"$summary"
if [ "$software" = yes ] && [ "${LODESTAR_ALLOW_SOFTWARE:-0}" != 1 ]; then
    say "the adapter is a software one ($adapter): not the GPU this check is for"
    echo "- stopped: software adapter" >>"$summary"
    exit 1
fi

# 2. The compare tables: each scene at its own resolution (CPU references from the
# bundle) and at $hd (a GPU nee render as reference). Guided rows with the default guide
# (the hemisphere grid), and the GPU's with the spatial × directional tree too.
methods=nee,gpu:nee,guided-nee,gpu:guided-nee,gpu:guided-nee@tree
status=$tests
for scene in door cornell; do
    file=$here/scenes/$scene/scene.json
    for size in native "$hd"; do
        name=$scene-$size
        if [ "$size" = native ]; then
            reference=$here/references/$scene-native.exr
            resolution=()
        else
            reference=$work/$name-reference.exr
            resolution=(--resolution "$size")
            say "== $name: reference, GPU nee for $reference_seconds s"
            "$lodestar" render "$file" --device gpu --integrator nee --seconds "$reference_seconds" --seed 99 \
                "${resolution[@]}" --out "$reference" 2>&1 | tee -a "$log" || status=1
        fi
        say "== $name: compare $methods, $seconds s each"
        if "$lodestar" compare "$file" --methods "$methods" --seconds "$seconds" --seed 41 "${resolution[@]}" \
            --reference "$reference" --out "$work/$name" 2>&1 | tee -a "$log"; then
            { echo; echo "## $name"; echo; grep '^|' "$work/$name/compare.md"; } >>"$summary"
        else
            status=1
            { echo; echo "## $name: compare FAILED (log.txt)"; } >>"$summary"
        fi
    done
done
(cd "$work" && tar czf "$out/results.tar.gz" --exclude='*.exr' --exclude='*.png' ./*/ 2>/dev/null)
rm -rf "$work"
cat "$summary"
exit "$status"
