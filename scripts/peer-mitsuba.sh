#!/usr/bin/env bash
# A peer to measure against: renders a Lodestar scene (scene.json) with Mitsuba 3's
# vectorised `path` integrator (llvm_ad_rgb) for SECONDS of wall time and writes OUT.exr
# and OUT.json (spp, paths/s, seconds). Mitsuba is installed with pip into its own
# virtual environment (.cache/mitsuba-venv; idempotent, a download of about 60 MB), so it
# stays out of the test command.
#
#   scripts/peer-mitsuba.sh SCENE.json SECONDS OUT.exr [--max-depth N] [--rr-depth N] [--checkpoints T1,T2,…]
#                                                      [--resolution WxH] [--threads N]
#
# The scene format's subset Mitsuba can render alike is converted: diffuse, conductor and
# dielectric materials, area lights, a constant environment, OBJ/PLY/inline meshes and
# quads, each shape naming its material (`lodestar compare --peer mitsuba` writes an OBJ's
# MTL materials inline first). Anything else (textures, image environments, a sun, …) is
# refused, naming it.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
venv=$root/.cache/mitsuba-venv
mitsuba_version=3.6.4

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi
}

if ! command -v python3 >/dev/null 2>&1 || ! python3 -c 'import ensurepip' >/dev/null 2>&1; then
    echo "peer-mitsuba: installing python3 and python3-venv" >&2
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends python3 python3-venv
fi
if ! "$venv/bin/python" -c "import mitsuba, numpy; assert mitsuba.__version__ == '$mitsuba_version'" >/dev/null 2>&1; then
    echo "peer-mitsuba: installing Mitsuba $mitsuba_version into $venv" >&2
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "mitsuba==$mitsuba_version" numpy
fi
exec "$venv/bin/python" "$root/scripts/peer_mitsuba.py" "$@"
