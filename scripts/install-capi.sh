#!/usr/bin/env bash
# Builds Lodestar's C library (release) and installs it into PREFIX for C and C++ engines:
#   PREFIX/lib/liblodestar.{so,a}
#   PREFIX/include/lodestar.h, lodestar.hpp        (the C API and its C++ wrapper)
#   PREFIX/lib/pkgconfig/lodestar.pc               (pkg-config --cflags --libs lodestar)
#   PREFIX/lib/cmake/lodestar/lodestarConfig.cmake (find_package(lodestar) → lodestar::lodestar)
#   PREFIX/lib/cmake/lodestar/lodestarConfigVersion.cmake (find_package(lodestar 0.1))
# Usage: scripts/install-capi.sh PREFIX   (CARGO_TARGET_DIR is honoured). Safe to rerun.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || { echo "usage: $0 PREFIX" >&2; exit 2; }
mkdir -p "$1"
prefix=$(cd "$1" && pwd)
. scripts/setup.sh

cargo build --release -p lodestar-capi
target=${CARGO_TARGET_DIR:-target}
version=$(sed -n 's/^version = "\(.*\)"/\1/p' adapters/capi/Cargo.toml | head -1)

install -d "$prefix/lib/pkgconfig" "$prefix/lib/cmake/lodestar" "$prefix/include"
install -m 0755 "$target/release/liblodestar.so" "$prefix/lib/"
install -m 0644 "$target/release/liblodestar.a" "$prefix/lib/"
install -m 0644 adapters/capi/include/lodestar.h adapters/capi/include/lodestar.hpp "$prefix/include/"

cat > "$prefix/lib/pkgconfig/lodestar.pc" <<EOF
prefix=$prefix
libdir=\${prefix}/lib
includedir=\${prefix}/include

Name: lodestar
Description: Path guiding by reinforcement learning (Lodestar's C API and C++ wrapper)
Version: $version
Cflags: -I\${includedir}
Libs: -L\${libdir} -Wl,-rpath,\${libdir} -llodestar
Libs.private: -lpthread -ldl -lm
EOF

cat > "$prefix/lib/cmake/lodestar/lodestarConfig.cmake" <<EOF
# find_package(lodestar) gives the imported target lodestar::lodestar (the shared library).
get_filename_component(_lodestar_prefix "\${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
if(NOT TARGET lodestar::lodestar)
  add_library(lodestar::lodestar SHARED IMPORTED)
  set_target_properties(lodestar::lodestar PROPERTIES
    IMPORTED_LOCATION "\${_lodestar_prefix}/lib/liblodestar.so"
    INTERFACE_INCLUDE_DIRECTORIES "\${_lodestar_prefix}/include")
endif()
set(lodestar_VERSION "$version")
unset(_lodestar_prefix)
EOF

cat > "$prefix/lib/cmake/lodestar/lodestarConfigVersion.cmake" <<EOF
# find_package(lodestar X.Y): compatible within one minor version while the major is 0
# (within one major version after), and never with a request newer than this one.
set(PACKAGE_VERSION "$version")
string(REGEX MATCH "^[0-9]+\\\\.[0-9]+" _lodestar_have "\${PACKAGE_VERSION}")
string(REGEX MATCH "^[0-9]+\\\\.[0-9]+" _lodestar_want "\${PACKAGE_FIND_VERSION}")
string(REGEX MATCH "^[0-9]+" _lodestar_major "\${PACKAGE_VERSION}")
string(REGEX MATCH "^[0-9]+" _lodestar_want_major "\${PACKAGE_FIND_VERSION}")
if(PACKAGE_FIND_VERSION VERSION_GREATER PACKAGE_VERSION)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
elseif(NOT _lodestar_major STREQUAL _lodestar_want_major)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
elseif(_lodestar_major STREQUAL "0" AND NOT _lodestar_want STREQUAL "" AND NOT _lodestar_have STREQUAL _lodestar_want)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
else()
  set(PACKAGE_VERSION_COMPATIBLE TRUE)
  if(PACKAGE_FIND_VERSION STREQUAL PACKAGE_VERSION)
    set(PACKAGE_VERSION_EXACT TRUE)
  endif()
endif()
unset(_lodestar_have)
unset(_lodestar_want)
unset(_lodestar_major)
unset(_lodestar_want_major)
EOF

echo "install-capi: liblodestar $version in $prefix (pkg-config: PKG_CONFIG_PATH=$prefix/lib/pkgconfig)"
