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
