#!/usr/bin/env bash
# Installs what building and testing Lodestar needs on a fresh Debian machine, and
# nothing that is already there: a stable Rust toolchain with rustfmt and clippy, C and
# C++ compilers (build scripts; the C API's C test and C++ example), pkg-config and CMake
# (which find the installed C library) and valgrind (which runs those clean). Safe to run any number of times.
set -euo pipefail

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi
}

missing_packages=()
command -v cc >/dev/null 2>&1 && command -v g++ >/dev/null 2>&1 || missing_packages+=(build-essential)
command -v valgrind >/dev/null 2>&1 || missing_packages+=(valgrind)
command -v curl >/dev/null 2>&1 || missing_packages+=(curl ca-certificates)
command -v pkg-config >/dev/null 2>&1 || missing_packages+=(pkg-config)
command -v cmake >/dev/null 2>&1 || missing_packages+=(cmake)
if [ ${#missing_packages[@]} -gt 0 ]; then
    echo "setup: installing ${missing_packages[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing_packages[@]}"
fi

if [ -f "$HOME/.cargo/env" ]; then
    # shellcheck disable=SC1091
    . "$HOME/.cargo/env"
fi
if ! command -v cargo >/dev/null 2>&1; then
    echo "setup: installing the stable Rust toolchain (rustup)"
    curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal --default-toolchain stable
    # shellcheck disable=SC1091
    . "$HOME/.cargo/env"
fi
if command -v rustup >/dev/null 2>&1; then
    for component in rustfmt clippy; do
        rustup component list --installed 2>/dev/null | grep -q "^$component" || rustup component add "$component"
    done
fi
