#!/usr/bin/env bash
# scripts/slurm-build against a stand-in sbatch that runs each job at once (an array's tasks one
# after the other, in reverse, with SLURM_ARRAY_TASK_ID set): the plan job submits the read and
# count arrays and the grid, the grid the bin and cells arrays and the upper step, the upper step
# the nodes array and the finish, each after the one before, and the file is the bytes of
# `facetree build` with the same options.
#   slurm_build_test.sh FACETREE SOURCE_DIR
set -euo pipefail
facetree="$1" source="$2"
work="$(mktemp -d "${TMPDIR:-/tmp}/facetree-slurm.XXXXXX")"
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
mkdir "$work/bin"
cat >"$work/bin/sbatch" <<'EOF'
#!/usr/bin/env bash
set -euo pipefail
array='' wrap='' output=/dev/null
for arg in "$@"; do
  case "$arg" in
    --array=*) array="${arg#--array=}" ;;
    --wrap=*) wrap="${arg#--wrap=}" ;;
    --output=*) output="${arg#--output=}" ;;
    --parsable|--mem=*|--time=*|--job-name=*|--dependency=*) ;;
    *) echo "sbatch stand-in: unexpected argument '$arg'" >&2; exit 2 ;;
  esac
done
echo "$*" >>"$SBATCH_LOG"
if [ -n "$array" ]; then
  for ((id = ${array#*-}; id >= ${array%-*}; id--)); do
    SLURM_ARRAY_TASK_ID=$id bash -c "$wrap" >"${output//%a/$id}" 2>&1
  done
else
  bash -c "$wrap" >"$output" 2>&1
fi
echo $((RANDOM + 1000))
EOF
chmod +x "$work/bin/sbatch"
"$facetree" gen terrain -n 200000 -o "$work/terrain.ply" --shuffle-faces >/dev/null
"$facetree" build "$work/terrain.ply" -o "$work/whole.fch" --memory 64M >/dev/null
PATH="$work/bin:$PATH" SBATCH_LOG="$work/sbatch.log" FACETREE="$facetree" \
  "$source/scripts/slurm-build" "$work/terrain.ply" "$work/staged.fch" "$work/stages" --memory 64M --cell-tasks 3 --read-tasks 2
cmp "$work/whole.fch" "$work/staged.fch"
for step in read count bin; do
  test "$(grep -c -- "--job-name=facetree-$step .*--array=0-1 " "$work/sbatch.log")" -eq 1
done
test "$(grep -c -- '--job-name=facetree-cells --dependency=afterok:[0-9]* --array=0-2 ' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-grid --dependency=afterok:[0-9]' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-upper --dependency=afterok:[0-9]' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-geometry .*--array=0-0 ' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-boxes --dependency=afterok:[0-9]' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-nodes .*--array=0-0 ' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-layout --dependency=afterok:[0-9]' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-place .*--array=0-1 ' "$work/sbatch.log")" -eq 1
test "$(grep -c -- '--job-name=facetree-finish --dependency=afterok:[0-9]' "$work/sbatch.log")" -eq 1
for log in logs/read-1.log logs/count-0.log plan.json grid.json logs/bin-1.log logs/cells-0.log upper.json \
  boxes.json layout.json logs/place-1.log logs/finish.log; do
  test -s "$work/stages/$log"
done
echo "slurm-build: plan, read, count, grid, bin and cells as arrays, finish after them; the bytes of facetree build"
