#!/usr/bin/env bash
# Installs a Vulkan driver for the GPU tracer's tests on a machine without a GPU: Mesa's
# software rasteriser lavapipe ("llvmpipe") and the Vulkan loader, from Debian's
# packages. Machines with a GPU driver already have what they need. Idempotent.
set -euo pipefail

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi
}

missing=()
for package in mesa-vulkan-drivers libvulkan1; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "provision-vulkan: installing ${missing[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
