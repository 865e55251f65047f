# Shared by the scripts: paths and the build step. Builds live outside the repository.
set -euo pipefail
FACETREE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FACETREE_BUILD_ROOT="${FACETREE_BUILD_ROOT:-${TMPDIR:-/tmp}/facetree-build-$(printf '%s' "$FACETREE_ROOT" | md5sum | cut -c1-8)}"
JOBS="${JOBS:-$(nproc)}"

# facetree_build NAME [cmake options...]: configure and build everything into $FACETREE_BUILD_ROOT/NAME.
# FACETREE_BUILD_TARGETS (space-separated) builds only those targets (and what they need).
facetree_build() {
  local name="$1"; shift
  local dir="$FACETREE_BUILD_ROOT/$name"
  cmake -S "$FACETREE_ROOT" -B "$dir" -G Ninja "$@" >/dev/null
  local targets=()
  [ -n "${FACETREE_BUILD_TARGETS:-}" ] && for t in $FACETREE_BUILD_TARGETS; do targets+=(--target "$t"); done
  cmake --build "$dir" -j "$JOBS" "${targets[@]}"
  BUILD_DIR="$dir"
}

# facetree_sanitized_build: the one sanitized build (clang, AddressSanitizer + UndefinedBehaviorSanitizer,
# libFuzzer's coverage in the modules the fuzz targets read with) into $FACETREE_BUILD_ROOT/sanitize:
# scripts/test --sanitize runs the suite in it, scripts/fuzz its fuzz targets, CI the sanitized smoke
# with its CLI. Installs clang and its runtimes when missing.
facetree_sanitized_build() {
  local runtime
  runtime=$(ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a 2>/dev/null | head -n1 || true)
  if ! command -v clang++ >/dev/null || [ -z "$runtime" ]; then
    FACETREE_SETUP_EXTRA="clang libclang-rt-14-dev ${FACETREE_SETUP_EXTRA:-}" "$FACETREE_ROOT/scripts/setup"
  fi
  facetree_build sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ -DFACETREE_FUZZ=ON \
    -DFACETREE_BUILD_BENCH=OFF -DFACETREE_PYTHON=OFF
}

# facetree_node_packages: the npm packages of scripts/viewer/package.json (the viewer page's three.js and
# 3d-tiles-renderer, the browser tests' playwright-core and gltf-validator) in $FACETREE_BUILD_ROOT/node,
# outside the repository; installed again only when the list changes. Installs Node.js and npm from
# Debian's packages where the machine has none. Sets NODE_MODULES.
facetree_node_packages() {
  if ! command -v npm >/dev/null; then
    FACETREE_SETUP_EXTRA="nodejs npm ${FACETREE_SETUP_EXTRA:-}" "$FACETREE_ROOT/scripts/setup"
  fi
  local dir="$FACETREE_BUILD_ROOT/node"
  NODE_MODULES="$dir/node_modules"
  if ! cmp -s "$FACETREE_ROOT/scripts/viewer/package.json" "$dir/package.json" || [ ! -d "$NODE_MODULES" ]; then
    mkdir -p "$dir"
    cp "$FACETREE_ROOT/scripts/viewer/package.json" "$dir/package.json"
    echo "setup: npm install in $dir" >&2
    (cd "$dir" && npm install --no-audit --no-fund --no-package-lock --loglevel=error >/dev/null)
  fi
}
