#!/usr/bin/env bash
# scripts/slurm-build on a real single-node Slurm (tests/stage/private_slurm.sh: Debian's munged,
# slurmctld and slurmd, started here and stopped at the end): the file is the bytes of `facetree
# build`, through job arrays and in one job; each job asks for --threads CPUs and for --memory
# plus a quarter; a rerun after success, after a deleted layout manifest, after a killed cells task
# and after a cancelled one gives the same bytes; a bad input fails the build with the reader's
# message and exit status, and leaves no output. The tiles of the file (--tiles) in a job array are
# the bytes of `facetree tiles`.
#   slurm_cluster_test.sh FACETREE SOURCE_DIR
set -euo pipefail
facetree="$1" source="$2"
source "$source/tests/stage/private_slurm.sh"
if ! slurm_daemons_installed; then
  echo "slurm_cluster_test: munged, slurmctld, slurmd or sbatch missing (scripts/setup installs them)" >&2
  exit 1
fi
dir="$(mktemp -d "${TMPDIR:-/tmp}/facetree-slurm.XXXXXX")"
cleanup() {
  slurm_stop
  [ -n "${KEEP:-}" ] || rm -rf "$dir"
}
trap cleanup EXIT
slurm_start "$dir/cluster"
build="$source/scripts/slurm-build"
fail() {
  echo "slurm_cluster_test: $*" >&2
  exit 1
}
# No job of the cluster is left pending or running.
expect_no_jobs() {
  local i
  for ((i = 0; i < 50; i++)); do
    [ -z "$(squeue -h)" ] && return 0
    sleep 0.2
  done
  squeue >&2
  fail "jobs left in the queue: $1"
}

"$facetree" gen terrain -n 200000 -o "$dir/terrain.ply" --shuffle-faces >/dev/null
"$facetree" build "$dir/terrain.ply" -o "$dir/whole.fch" --memory 64M >/dev/null
options=(--memory 64M --threads 2 --cell-tasks 3 --read-tasks 2)

# Every step of more than one task as a job array (jobs of at most 50,000 of the 199,712
# triangles).
FACETREE="$facetree" FACETREE_SLURM_JOB_FACES=50000 "$build" "$dir/terrain.ply" "$dir/arrays.fch" "$dir/work-arrays" \
  --wait --keep-work "${options[@]}" >"$dir/arrays.out"
cmp "$dir/whole.fch" "$dir/arrays.fch" || fail "job arrays: not the bytes of facetree build"
for log in cells-0 cells-1 cells-2 read-0 read-1 bin-0 bin-1; do
  [ -e "$dir/work-arrays/logs/job-$log.log" ] || fail "job arrays: no job array of $log"
done
grep -q "^hierarchy .* nodes" "$dir/arrays.out" || fail "job arrays: no report: $(cat "$dir/arrays.out")"
# The report's times and peak are the tasks', not the finish's alone.
grep -q "^time .* cells [0-9.]* s, .* total [0-9.]* s" "$dir/arrays.out" &&
  ! grep -q "cells 0.000 s\|total 0.000 s" "$dir/arrays.out" || fail "job arrays: no times: $(cat "$dir/arrays.out")"
peak=$(sed -n 's/^peak memory *\([0-9]*\)\..*/\1/p' "$dir/arrays.out")
[ "${peak:-0}" -ge 16 ] || fail "job arrays: a peak of ${peak:-?} MiB is the finish's own"
expect_no_jobs "after the job arrays"

# In one job (the default: jobs of up to 2^24 triangles), WORK kept; it asks for the threads and the
# cap.
work="$dir/work"
FACETREE="$facetree" "$build" "$dir/terrain.ply" "$dir/out.fch" "$work" --wait --keep-work "${options[@]}" \
  >"$dir/out.out"
cmp "$dir/whole.fch" "$dir/out.fch" || fail "one job: not the bytes of facetree build"
[ "$(wc -l <"$work/jobs")" = 1 ] || fail "one job: $(wc -l <"$work/jobs") jobs"
for id in $(cat "$work/jobs"); do
  scontrol -o show job "$id" | grep -q "NumCPUs=2 " || fail "job $id does not ask for 2 CPUs"
  scontrol -o show job "$id" | grep -q "MinMemoryNode=336M " || fail "job $id does not ask for 64M + 25% + 256M"
done

# A rerun after success: done already, the same bytes.
FACETREE="$facetree" "$build" "$dir/terrain.ply" "$dir/out.fch" "$work" --wait --keep-work "${options[@]}" \
  >"$dir/rerun.out"
cmp "$dir/whole.fch" "$dir/out.fch" || fail "rerun after success: not the same bytes"
grep -q "done already" "$work/logs/cells-0.log" || fail "rerun after success: cells task 0 made again"

# A rerun after the layout manifest was deleted: laid out and placed again.
rm "$work/layout.manifest"
FACETREE="$facetree" "$build" "$dir/terrain.ply" "$dir/out.fch" "$work" --wait --keep-work "${options[@]}" \
  >"$dir/relayout.out"
cmp "$dir/whole.fch" "$dir/out.fch" || fail "rerun after a deleted layout: not the same bytes"
"$facetree" verify "$dir/out.fch" >/dev/null || fail "rerun after a deleted layout: verify fails"

# A cells task killed (SIGKILL, the first time it runs): the build fails with its status and log,
# nothing is left pending, and the rerun redoes only that task.
cat >"$dir/killing-facetree" <<EOF
#!/usr/bin/env bash
if [ "\$2 \${*: -2}" = "cells --task 1" ] && [ ! -e "$dir/killed" ]; then
  touch "$dir/killed"
  kill -9 \$\$
fi
exec $(printf %q "$facetree") "\$@"
EOF
chmod +x "$dir/killing-facetree"
rm -f "$dir/killed.fch"
status=0
FACETREE="$dir/killing-facetree" FACETREE_SLURM_JOB_FACES=50000 "$build" "$dir/terrain.ply" "$dir/killed.fch" \
  "$dir/work-killed" --wait "${options[@]}" >"$dir/killed.out" 2>"$dir/killed.err" || status=$?
[ "$status" = 137 ] || fail "killed cells task: slurm-build exits $status, not 137: $(cat "$dir/killed.err")"
grep -q "cells task 1 failed with status 137" "$dir/killed.err" || fail "killed cells task: $(cat "$dir/killed.err")"
[ ! -e "$dir/killed.fch" ] || fail "killed cells task: an output was written"
expect_no_jobs "after a killed cells task"
FACETREE="$facetree" FACETREE_SLURM_JOB_FACES=50000 "$build" "$dir/terrain.ply" "$dir/killed.fch" "$dir/work-killed" \
  --wait --keep-work "${options[@]}" >"$dir/resumed.out"
cmp "$dir/whole.fch" "$dir/killed.fch" || fail "resumed after a killed task: not the same bytes"
grep -q "done already" "$dir/work-killed/logs/cells-0.log" || fail "resume: cells task 0 made again"
grep -q "cells task 1: done$" "$dir/work-killed/logs/cells-1.log" || fail "resume: cells task 1 not made"

# A cells task cancelled while it runs: the build stops (no job left pending), --wait says so.
cat >"$dir/slow-facetree" <<EOF
#!/usr/bin/env bash
[ "\$2" = cells ] && sleep 30
exec $(printf %q "$facetree") "\$@"
EOF
chmod +x "$dir/slow-facetree"
status=0
FACETREE="$dir/slow-facetree" FACETREE_SLURM_JOB_FACES=50000 "$build" "$dir/terrain.ply" "$dir/cancelled.fch" \
  "$dir/work-cancelled" --wait "${options[@]}" >"$dir/cancelled.out" 2>"$dir/cancelled.err" &
waiting=$!
for ((i = 0; i < 300; i++)); do
  array=$(squeue -h -n facetree-cells -o %A | head -n 1)
  [ -n "$array" ] && [ -n "$(squeue -h -n facetree-cells -t RUNNING)" ] && break
  sleep 0.2
done
[ -n "$array" ] || fail "cancelled task: the cells array never ran"
scancel "$array"
wait "$waiting" || status=$?
[ "$status" != 0 ] || fail "cancelled task: slurm-build --wait exits 0"
# Which --wait sees first depends on timing: the job array cancelled ("stopped without finishing")
# or its running task's record of the SIGTERM that scancel sent it; either names what happened.
grep -q -e "stopped without finishing" -e "cells task [0-9]* failed with status 143, killed by signal 15" \
  "$dir/cancelled.err" || fail "cancelled task: $(cat "$dir/cancelled.err")"
[ ! -e "$dir/cancelled.fch" ] || fail "cancelled task: an output was written"
expect_no_jobs "after a cancelled task"
FACETREE="$facetree" "$build" "$dir/terrain.ply" "$dir/cancelled.fch" "$dir/work-cancelled" --wait \
  "${options[@]}" >/dev/null
cmp "$dir/whole.fch" "$dir/cancelled.fch" || fail "resumed after a cancelled task: not the same bytes"
[ ! -e "$dir/work-cancelled" ] || fail "resumed after a cancelled task: WORK left after success"

# The file's tiles as tasks (--tiles): the subtrees in a job array, two at once in a job sharing
# the cap; the bytes of `facetree tiles`. A file that is not a cluster file fails the plan.
"$facetree" tiles "$dir/whole.fch" -o "$dir/tiles-one" --tile-faces 4096 --memory 64M >/dev/null
FACETREE="$facetree" FACETREE_SLURM_JOB_FACES=50000 "$build" --tiles "$dir/whole.fch" "$dir/tiles-slurm" \
  "$dir/work-tiles" --wait --keep-work --tile-faces 4096 --memory 64M --tasks 6 >"$dir/tiles.out"
diff -r "$dir/tiles-one" "$dir/tiles-slurm" >/dev/null || fail "tiles: not the bytes of facetree tiles"
[ -e "$dir/work-tiles/logs/job-tiles-1.log" ] || fail "tiles: no job array of tiles tasks"
grep -q "tiles-slurm: [0-9]* tiles ([0-9]* leaves)" "$dir/tiles.out" || fail "tiles: no report: $(cat "$dir/tiles.out")"
grep -q "tiles task 0: done" "$dir/work-tiles/logs/tiles-0.log" || fail "tiles: task 0 not run"
expect_no_jobs "after the tiles"
status=0
FACETREE="$facetree" "$build" --tiles "$dir/terrain.ply" "$dir/tiles-bad" "$dir/work-tiles-bad" --wait \
  --memory 64M >"$dir/tiles-bad.out" 2>"$dir/tiles-bad.err" || status=$?
[ "$status" = 3 ] || fail "tiles of a mesh: slurm-build exits $status, not 3: $(cat "$dir/tiles-bad.err")"
grep -q "tiles-plan task 0 failed with status 3" "$dir/tiles-bad.err" || fail "tiles of a mesh: $(cat "$dir/tiles-bad.err")"
[ ! -e "$dir/tiles-bad" ] || fail "tiles of a mesh: an output was written"
expect_no_jobs "after the tiles of a mesh"

# A bad input: the plan's error and exit status, no output.
head -c 20000 "$dir/terrain.ply" >"$dir/short.ply"
status=0
FACETREE="$facetree" "$build" "$dir/short.ply" "$dir/short.fch" "$dir/work-short" --wait "${options[@]}" \
  >"$dir/short.out" 2>"$dir/short.err" || status=$?
[ "$status" = 3 ] || fail "bad input: slurm-build exits $status, not 3: $(cat "$dir/short.err")"
grep -q "plan task 0 failed with status 3" "$dir/short.err" || fail "bad input: $(cat "$dir/short.err")"
grep -q "short.ply: .*" "$dir/short.err" || fail "bad input: the reader's message missing: $(cat "$dir/short.err")"
[ ! -e "$dir/short.fch" ] || fail "bad input: an output was written"
expect_no_jobs "after a bad input"
echo "slurm-build on a private Slurm: the bytes of facetree build in job arrays and in one job, the tiles' bytes, the CPUs and memory asked for, reruns after success, a deleted layout, a killed and a cancelled cells task, and a bad input's error"
