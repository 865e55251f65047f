#!/usr/bin/env bash
# End-to-end runs of a sanitized facetree (AddressSanitizer + UndefinedBehaviorSanitizer, as
# scripts/fuzz builds it): every reader, the in-core and out-of-core builds with both metrics,
# two threads and every branching factor, the mesh and cluster file writers, and every command
# that reads a cluster file. A sanitizer report aborts the command (-fno-sanitize-recover, leaks
# checked at exit), and any command that fails, `verify` included, fails the run.
# CI runs this after the fuzzers (scripts/test --ci); the whole suite under the sanitizers is
# `scripts/test --sanitize`.
#   tests/cli/sanitized_smoke.sh FACETREE WORKDIR [SHARED_DATA]
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 FACETREE WORKDIR [SHARED_DATA]" >&2
  exit 2
fi
bin="$1"
work="$2"
shared="${3:-}"
data="$(cd "$(dirname "$0")/../data/valid" && pwd)"
rm -rf "$work"
mkdir -p "$work"
cd "$work"

run() {
  echo "smoke: facetree $*"
  local start=$SECONDS
  "$bin" "$@" >last.out
  echo "smoke:   $((SECONDS - start)) s"
}

# A terrain with shuffled vertices and faces (the out-of-core read resolves spilled positions).
run gen terrain -n 120000 --shuffle-vertices --shuffle-faces -o t.ply
run stats t.ply

# In core: two threads for the boxes, a reordered mesh out as PLY and as Draco.
run build t.ply -o in.fch --threads 2 --mesh-out m.ply
run build t.ply -o b4.fch --branching 4 --mesh-out m.drc --draco-bits 14
# Out of core, forced by a small cap and small cells: both metrics, b = 2 and 8, welding.
run build t.ply -o ooc.fch --memory 64M --cell-faces 8000 --threads 2
run build t.ply -o garland.fch --memory 64M --cell-faces 8000 --threads 2 --metric garland --branching 8
run build t.ply -o weld.fch --memory 64M --cell-faces 8000 --weld
for f in in b4 ooc garland weld; do run verify "$f.fch" t.ply; done

# The other readers: Draco (the mesh written above), zstd from standard input, OBJ, STL.
run build m.drc -o drc.fch
echo "smoke: facetree build - (pyramid.ply.zst on standard input)"
"$bin" build - -o stdin.fch <"$data/pyramid.ply.zst" >last.out
run build "$data/pyramid.obj" -o obj.fch
run build "$data/pyramid_ascii.stl" -o stl.fch
run build "$data/pyramid_binary_solid_header.stl" -o stlb.fch
for f in drc stdin obj stl stlb; do run verify "$f.fch"; done
if [ -n "$shared" ] && [ -f "$shared/bunny_zipper.ply.zst" ]; then
  run build "$shared/bunny_zipper.ply.zst" -o bunny.fch --memory 64M --cell-faces 10000
  run verify bunny.fch "$shared/bunny_zipper.ply.zst"
fi

# What reads a cluster file.
run info in.fch --fit-cuts 100,1000
run truncate in.fch -o cut.fch --nodes 500
run verify cut.fch
run render ooc.fch --cut 64 -o ooc.png --width 160 --height 120
run export garland.fch --depth 4 -o export.ply
run build t.ply --method octree
echo "smoke: all passed"
