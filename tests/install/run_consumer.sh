#!/usr/bin/env bash
# Installs the built facetree into a scratch prefix and builds and runs a consumer project with it.
set -euo pipefail
build_dir="$1"; source_dir="$2"
work="$(mktemp -d "${TMPDIR:-/tmp}/facetree-install.XXXXXX")"
trap 'rm -rf "$work"' EXIT
cmake --install "$build_dir" --prefix "$work/prefix" >/dev/null
test -f "$work/prefix/include/facetree.h"
for module in error stream merge storage grid io query picture generate tiles; do test -f "$work/prefix/include/facetree/$module.h"; done
# Only the public tree is installed: no module's internal header.
test "$(find "$work/prefix/include" -name '*.h' | wc -l)" -eq 11
# The build's own compiler: a sanitized library needs its compiler's sanitizer runtime.
compiler=$(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' "$build_dir/CMakeCache.txt")
cmake -S "$source_dir/tests/install/consumer" -B "$work/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_COMPILER="$compiler" -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/build" >/dev/null
"$work/build/consumer"
