#!/usr/bin/env bash
# Runs every cargo-fuzz target for SECONDS each (default 30; CI's smoke run) on stable
# Rust without a sanitizer, seeding the corpora from the repository's scenes and meshes.
# Prints each target's executions; fails on the first crash (the input is left in
# fuzz/artifacts/TARGET). Longer runs: ./scripts/fuzz.sh 600 [TARGET...]
# AddressSanitizer (about 5× slower): RUSTC_BOOTSTRAP=1 cargo fuzz run TARGET
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/setup.sh

seconds=${1:-30}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene_json mesh guide_bytes update_stream capi_calls foreign_scene)

command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked --version 0.13.2

seed_corpora() {
    mkdir -p fuzz/corpus/{scene_json,mesh,guide_bytes,update_stream,capi_calls,foreign_scene}
    for scene in scenes/*/scene.json; do
        cp "$scene" "fuzz/corpus/scene_json/$(basename "$(dirname "$scene")").json"
    done
    # Mesh inputs: a selector byte (even: OBJ, odd: PLY), then the file.
    for mesh in scenes/*/meshes/*.obj; do
        { printf '\000'; cat "$mesh"; } > "fuzz/corpus/mesh/obj-$(basename "$mesh")"
    done
    local header='ply\nformat %s 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n'
    { printf '\001'; printf "$header" ascii; printf '0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n'; } > fuzz/corpus/mesh/quad-ascii.ply
    {
        printf '\001'; printf "$header" binary_little_endian
        printf '\000\000\000\000\000\000\000\000\000\000\000\000'  # (0, 0, 0)
        printf '\000\000\200\077\000\000\000\000\000\000\000\000'  # (1, 0, 0)
        printf '\000\000\200\077\000\000\200\077\000\000\000\000'  # (1, 1, 0)
        printf '\000\000\000\000\000\000\200\077\000\000\000\000'  # (0, 1, 0)
        printf '\004\000\000\000\000\001\000\000\000\002\000\000\000\003\000\000\000'
    } > fuzz/corpus/mesh/quad-binary.ply
    # Foreign scenes: a selector byte (even: pbrt, odd: Mitsuba), then the file; small
    # ones whose meshes resolve beside the original Cornell box, and the real ones.
    # The C ABI's environment guide: 0xE5, then its config, a 4 × 2 map, a sun and calls.
    head -c 400 /dev/zero | tr '\000' '\077' | { printf '\345\000\000\001\000\004\002\000\003\001'; cat; } \
        > fuzz/corpus/capi_calls/environment
    { printf '\000'; cat scenes/veach-ajar/scene.pbrt; } > fuzz/corpus/foreign_scene/veach-ajar.pbrt
    for xml in scenes/*/scene.xml; do
        { printf '\001'; cat "$xml"; } > "fuzz/corpus/foreign_scene/$(basename "$(dirname "$xml")").xml"
    done
    {
        printf '\000'
        printf 'LookAt 0 1 4 0 1 0 0 1 0\nCamera "perspective" "float fov" 40\nFilm "image" "integer xresolution" 8 "integer yresolution" 8\n'
        printf 'WorldBegin\nTexture "t" "spectrum" "checkerboard" "float uscale" 4 "rgb tex1" [0.2 0.2 0.2]\n'
        printf 'MakeNamedMaterial "m" "string type" "matte" "texture Kd" "t"\nNamedMaterial "m"\n'
        printf 'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [4 4 4]\nTranslate 0 1 0\n'
        printf 'Shape "trianglemesh" "integer indices" [0 1 2] "point P" [0 0 0 1 0 0 0 0 1] "normal N" [0 -1 0 0 -1 0 0 -1 0]\nAttributeEnd\nWorldEnd\n'
    } > fuzz/corpus/foreign_scene/small.pbrt
    {
        printf '\001<scene version="0.5.0"><sensor type="perspective"><float name="fov" value="45"/>'
        printf '<transform name="toWorld"><lookat origin="0, 1, 4" target="0, 1, 0" up="0, 1, 0"/></transform></sensor>'
        printf '<shape type="obj"><string name="filename" value="CornellBox-Original.obj"/></shape>'
        printf '<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape></scene>'
    } > fuzz/corpus/foreign_scene/small.xml
}

seed_corpora
# Build once, then run the binaries themselves: a failed build is a build error, never
# mistaken for a crash, and the sources can change while a long run goes on.
cargo fuzz build --sanitizer none
binaries="fuzz/target/$(rustc -vV | sed -n 's/^host: //p')/release"

# One target for `seconds`, logging into `logs` (its tail is printed if it crashes).
run_target() {
    local target=$1 log="$logs/$1.log" start=$SECONDS
    mkdir -p "fuzz/artifacts/$target"
    if ! "$binaries/$target" "fuzz/corpus/$target" -artifact_prefix="fuzz/artifacts/$target/" \
        -max_total_time="$seconds" -print_final_stats=1 -max_len=65536 >"$log" 2>&1; then
        tail -40 "$log"
        echo "fuzz: $target crashed; the input is in fuzz/artifacts/$target" >&2
        return 1
    fi
    local runs
    runs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | awk '{print $2}')
    echo "fuzz: $target: ${runs:-?} executions in $((SECONDS - start)) s, no crash"
}

# libFuzzer runs on one core: as many targets at once as there are cores, each for its
# full time.
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT
parallel=$(nproc)
failed=0
pids=()
for target in "${targets[@]}"; do
    run_target "$target" &
    pids+=($!)
    if [ ${#pids[@]} -ge "$parallel" ]; then
        wait "${pids[0]}" || failed=1
        pids=("${pids[@]:1}")
    fi
done
for pid in "${pids[@]}"; do
    wait "$pid" || failed=1
done
exit $failed
