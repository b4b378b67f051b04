#!/usr/bin/env bash
# Provisions Embree 4 for the guiding-embree adapter. On a system whose pkg-config knows
# `embree4` (Debian 13 and later) there is nothing to do. Otherwise (Debian 12 ships only
# Embree 3) it fetches the embreex 4.4.0.post1 wheel from PyPI, checks its sha256, and
# unpacks the Embree 4.4 and TBB shared libraries it carries into .cache/embree4/lib
# (or $LODESTAR_EMBREE_DIR/lib), with a libembree4.so link for the linker. Idempotent:
# a second run finds the checked libraries and does nothing. Nothing downloads at build
# time; guiding-embree's build script looks here after EMBREE4_LIB_DIR and pkg-config.
set -euo pipefail
cd "$(dirname "$0")/.."

wheel_version=4.4.0.post1
wheel_sha256=2cd0f7d5c6342e6247e31f700761689cae7829454d8c6de0c41e62124a023e1f
library=libembree4-4aef3270.so.4
directory=${LODESTAR_EMBREE_DIR:-$PWD/.cache/embree4}
stamp="$directory/lib/.provisioned-$wheel_sha256"

if pkg-config --exists embree4 2>/dev/null; then
    echo "provision-embree: using the system's Embree $(pkg-config --modversion embree4)"
    exit 0
fi
if [ -f "$stamp" ] && [ -f "$directory/lib/$library" ]; then
    exit 0
fi

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi
}
if ! python3 -m pip --version >/dev/null 2>&1; then
    echo "provision-embree: installing python3-pip"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends python3-pip
fi

download=$(mktemp -d)
trap 'rm -rf "$download"' EXIT
echo "provision-embree: fetching the embreex $wheel_version wheel (Embree 4.4)"
python3 -m pip download --quiet --no-deps --only-binary=:all: --platform manylinux_2_28_x86_64 \
    --python-version 3.11 --implementation cp --abi cp311 "embreex==$wheel_version" -d "$download"
wheel=$(ls "$download"/embreex-*.whl)
echo "$wheel_sha256  $wheel" | sha256sum --check --quiet || {
    echo "provision-embree: $wheel does not have the expected sha256 $wheel_sha256" >&2
    exit 1
}
mkdir -p "$directory/lib"
python3 - "$wheel" "$directory/lib" <<'PYTHON'
import os, sys, zipfile
wheel, target = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as archive:
    for entry in archive.infolist():
        if entry.filename.startswith("embreex.libs/") and not entry.is_dir():
            path = os.path.join(target, os.path.basename(entry.filename))
            with archive.open(entry) as source, open(path, "wb") as out:
                out.write(source.read())
            os.chmod(path, 0o755)
PYTHON
ln -sf "$library" "$directory/lib/libembree4.so"
touch "$stamp"
echo "provision-embree: Embree 4.4 is in $directory/lib"
