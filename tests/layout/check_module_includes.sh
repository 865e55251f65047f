#!/usr/bin/env bash
# The modules' dependencies run one way: cli on grid, picture and generate (and what they expose),
# grid on io, merge, storage and stream, picture on query, query on io, merge and storage, generate
# on io and merge, tiles on io and stream, io on merge and storage, merge, storage and stream on
# nothing. The compiler already refuses another module's internal header (a module sees only
# include/ and its own folder); this checks which public headers each module includes, and that no
# source reaches outside its folder by a relative path.
# The Python package depends on the library only, never on the command line.
#   check_module_includes.sh SOURCE_DIR
set -euo pipefail
cd "$1"
declare -A allowed=(
  [stream]="error stream"
  [merge]="error merge"
  [storage]="error storage"
  [io]="error merge storage io"
  [grid]="error stream merge storage io grid"
  [query]="error merge storage io query"
  [picture]="error merge storage io query picture"
  [generate]="error merge io generate"
  [tiles]="error stream merge storage io tiles"
  [cli]="error stream merge storage io grid query picture generate tiles"
  [python/src]="error stream merge storage io grid query picture generate tiles"
)
failed=0
for module in "${!allowed[@]}"; do
  while IFS= read -r line; do
    file="${line%%:*}"
    header="$(sed -n 's/.*#include [<"]facetree\/\([a-z_]*\)\.h[>"].*/\1/p' <<<"$line")"
    case " ${allowed[$module]} " in
      *" $header "*) ;;
      *) echo "$file: includes facetree/$header.h, which $module must not depend on" >&2; failed=1 ;;
    esac
  done < <(grep -rn --include='*.cpp' --include='*.h' '#include [<"]facetree/' "$module" || true)
  if grep -rn --include='*.cpp' --include='*.h' '#include "\.\./' "$module"; then
    echo "$module: includes by a relative path outside its folder" >&2
    failed=1
  fi
done
# The package stands on the library alone: its sources include only their own headers and the
# public ones, and its build names nothing of the command line's folder.
while IFS= read -r line; do
  file="${line%%:*}"
  header="$(sed -n 's/.*#include "\([^"]*\)".*/\1/p' <<<"$line")"
  case "$header" in
    facetree/*) ;;
    *) [ -f "python/src/$header" ] || { echo "$file: includes \"$header\", not a header of python/src" >&2; failed=1; } ;;
  esac
done < <(grep -rn --include='*.cpp' --include='*.h' '#include "' python/src || true)
if grep -n 'cli' python/CMakeLists.txt; then
  echo "python/CMakeLists.txt: names the command line's folder or targets" >&2
  failed=1
fi
# The public headers themselves: each includes only the modules below it.
declare -A below=([error]="" [stream]="error" [merge]="error" [storage]="error" [io]="error merge storage"
                 [grid]="error stream merge storage io" [query]="error merge storage io"
                 [picture]="error merge storage io query" [generate]="error merge io" [tiles]="error merge storage io")
for header in "${!below[@]}"; do
  while IFS= read -r included; do
    case " ${below[$header]} " in
      *" $included "*) ;;
      *) echo "include/facetree/$header.h: includes facetree/$included.h" >&2; failed=1 ;;
    esac
  done < <(sed -n 's/.*#include [<"]facetree\/\([a-z_]*\)\.h[>"].*/\1/p' "include/facetree/$header.h")
done
[ "$failed" -eq 0 ] && echo "module includes: one way (stream, merge, storage <- io <- grid, query <- cli, python)"
exit "$failed"
