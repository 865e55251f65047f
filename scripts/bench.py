#!/usr/bin/env python3
"""facetree benchmarks: each case run several times, medians reported, comparisons as ratios
against a baseline measured in the same invocation (the machine is shared and noisy). Every
run also records its process CPU time (user + system, from wait4): on a loaded machine CPU
time moves far less than wall time, so ratios are given for both.

Sections (Willmott 2000, ch. 5, tables and figures named):
  read       mesh reading throughput (facetree stats) against `zstd -dc` of the same file
  build      file to hierarchy with boxes per mesh: phases, peak RSS, height/balanced, degree;
             ratio to the read time of the same mesh
  profile    Tables 5 and 8: time per phase for both metrics on dragon_vrip
  balance    Table 6 and Fig. 73: height against balanced height and box time, default metric
             against --metric garland per mesh; heights for k in {0, 1e-5, 1e-4, 1e-3} with and
             without the balance guard; cluster pictures of one cut (dragon_vrip,
             openfoam_buildings, both metrics)
  scaling    Figs 77-78: time and peak RSS against faces over the shared and generated meshes,
             log-log slopes, average and maximum dual-edge degree per mesh; the full run adds a
             generated 50M-face terrain built out of core under --memory 1G (one run, marked
             "memory": "1G" in the JSON; slopes fitted without it and given again with it)
  octree     Fig. 80: face clustering time / tightest-fit octree time per mesh; the same ratio
             in instructions (callgrind) on bunny_zipper
  branching  cluster file size for branching 2, 4, 8 (verified) and per truncation prefix
  flat       Figs 69-71: flat regular grids: time and maximum dual-edge degree for the default
             metric against the constant-cost and Garland metrics, and the log-log slope
  rounds     the merge in rounds against the exact greedy order, per mesh (quick: QUICK_MESHES, full:
             every shared mesh): `build MESH -o OUT.fch` with default threads, with --threads 1 and
             with --order exact, and `build --method octree`, interleaved per repetition (whole
             processes: wall, CPU, peak RSS from wait4); phases and rounds from --json; the fit of
             cuts of 1,000 and 100,000 clusters (`info --fit-cuts`) against the exact order's; the
             top's cuts of 12, 100 and 1,000 against eq. 84's order to the root (`--top 0`), and the
             balance of the cut of 100 (clusters under 1% of the average cluster's area); the worst
             fit and boxes over every cut of 2 to 64 clusters, and how many are over 1.10 and 1.0;
             whether --threads 1 and the default give the same bytes; the targets as checks
  python     the Python binding's overhead on dragon_vrip: facetree.build from the arrays read_mesh gives
             (float32, uint32: used in place) against the same library calls from C++ on the same mesh
             (tests/python/library_build.cpp), interleaved, whole processes; time and the resident set
             the build adds (its peak over the resident set before it); and the same from float64 /
             int64 arrays, which are converted (copied); with the issue's targets as checks
  outofcore  a generated terrain (quick 2M faces, full 10M) and its shuffled twin built
             with --memory 64M, 256M, 1G and in core (--memory 16G: the job's in-core path): time,
             peak RSS (the job's --json and wait4's ru_maxrss, what /usr/bin/time prints), temporary
             and file bytes, cells, leaves, height, ratios to in core; and the quality of forced
             out-of-core builds (--cell-faces) of meshes that fit against the in-core one: eFit
             summed over cuts of 1,000 and 100,000 clusters (`info --fit-cuts`), heights, ratios;
             and the subdivided dragon (`gen subdivide dragon_vrip --levels L`), coherent and
             shuffled: 14M faces at --memory 64M (quick and full) and 55.8M at 256M (full), with
             the pipeline's targets as checks (time, faces/s, cap, temporary peak against the file);
             and every shared mesh of 1M faces or more at --memory 64M against in core (cut fits
             within 10%, heights within 1.25x, as checks)
  queries    queries through the hierarchy (tests/query/query_bench, built with -DFACETREE_QUERY_BENCH=ON
             against Debian's libembree-dev): the branching experiment (Willmott 2000, sec. 5.5.1) for
             b = 2, 4 and 8 on every shared mesh, whole and truncated to 10% and 1% of its nodes:
             closest and any hits of camera and random rays, box overlap and nearest points on one
             thread, queries a second, boxes and triangles tested a query; then Embree 3.13
             (rtcIntersect1 over a scene built at medium quality) on the same rays at the best b:
             the same triangle and t on every shared mesh, and the time on dragon_vrip with 1M camera
             and 1M random rays on one thread and on two, alternating, with the targets as checks;
             in the full run, 1M rays on the 56M-face dragon's file through the lazy reader under
             --memory 256M, sent 65,536 at a time (rays a second, the process's peak RSS against
             the cap)
  tiles      `facetree tiles` on dragon_vrip (quick and full) and the 14M- and 56M-face dragons (full,
             under 64M and 256M): the tiling and the build that wrote the file alternating, with and
             without Draco; sizes against the leaves', peak RSS against the cap; the same tiles as the
             stage commands' tasks one after another (their seconds, the largest task's peak, the same
             bytes); the targets as checks
  speed      with --baseline-facetree BIN (an earlier build, e.g. the previous commit's): dragon_vrip
             in core (quick and full) and the 14M-face dragon at --memory 64M (full), built by both
             binaries alternately in one run, medians of whole processes' wall and CPU; the ratio
             new / baseline at most 1.10 as the check (skipped without a baseline)

The per-mesh builds (default metric, Garland metric, octree) run interleaved, once per
repetition, and are shared by build, profile, balance, scaling and octree.

Writes OUT/bench.json (and OUT/pictures/*.png) and prints a table per section.

Budget on the 2-CPU shared machine, measured on 2026-11-21 (/usr/bin/time -v, another helper's
out-of-core builds running alongside): --quick 6.3 minutes of wall time, 5.7 CPU minutes, at load
1.7-4.0 (outofcore 3.0 of them: one run per case, 8 builds of 2M faces, 6 quality builds of ~1M);
the full run 41.5 minutes, 37.2 CPU minutes, at load 1.4-9.3 (mean 4.1). Full run per section: build
8.2 min (the shared per-mesh builds), balance 2.4, scaling 9.1 (the 50M-face point's build 6.0 of them,
generating its 950 MB PLY 6 s), flat 7.2 (Garland on the 640k grid: 87 s a run),
outofcore 13.3 (one run per case: three would add some 27 CPU minutes and pass the hour), the rest
under a minute each. OUT/bench.json records each section's wall time (section_seconds) and the load
average at its end.
"""
import argparse
import json
import math
import os
import pathlib
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

SHARED = pathlib.Path(__file__).resolve().parent.parent.parent / "shared" / "data"
QUICK_MESHES = ["bunny_zipper", "dragon_vrip", "openfoam_buildings", "turbine_blade_200k"]
PROFILE_MESH = "dragon_vrip"
PICTURE_MESHES = ["dragon_vrip", "openfoam_buildings"]
CALLGRIND_MESH = "bunny_zipper"  # octree ratio in instructions: ~1 min of callgrind
PICTURE_CUT = 64
# Garland's metric builds deep, unbalanced trees (O(n h) boxes): fg_hawaii (3.2M faces, 1.2M of
# them zero-area) had not finished after 30 CPU seconds. Larger meshes run the default only.
GARLAND_MAX_FACES = 1_500_000
K_VALUES = [0.0, 1e-5, 1e-4, 1e-3]  # 1e-4 is the default: its runs are the default-metric runs
# Generated meshes for the scaling section (facetree gen terrain: a height field, closed to no
# optimisation of ours).
SCALING_QUICK = [100_000, 300_000]
SCALING_FULL = [1_000_000, 2_000_000, 4_000_000]
# 50M faces in core would take ~8.6 GB and ~12 minutes: the full run builds it out of core under
# a 1G cap (facetree build -o --memory), once (the tree is deterministic; the run takes ~10 minutes
# on the shared 2-CPU machine). Skipped in --quick. Its time and peak RSS are not those of an
# in-core build (bin and cells passes, the file written; RSS bounded by the cap), so the slopes
# are fitted over the in-core points and given again with it.
SCALING_OUT_OF_CORE = [50_000_000]
SCALING_OUT_OF_CORE_CAP = "1G"
OUT_OF_CORE_CAPS = ["64M", "256M", "1G", None]  # None: in core
# Without --memory the CLI takes its older in-core path (no job report); a cap far above the mesh
# gives the job's in-core path, whose report and writer the out-of-core runs share.
IN_CORE_CAP = "16G"
OUT_OF_CORE_FACES_QUICK = 2_000_000
OUT_OF_CORE_FACES_FULL = 10_000_000
# Quality: meshes that fit, built in core and out of core forced with cells of at most N faces.
# (name, generated kind and faces, or shared)
QUALITY_MESHES = [("dragon_vrip", None, None), ("terrain 1M", "terrain", 1_000_000),
                  ("assembly 331k", "assembly", 331_000)]
QUALITY_CELL_FACES = [2_000, 20_000, 100_000]
# In the smallest cells, cut fits (sum of area x eFit) within 15% of in core (a check).
QUALITY_SMALL_CELLS_FIT_BOUND = 1.15
FIT_CUTS = [1000, 10_000, 100_000]
# Coherence of the top: a cut's sum of box surface areas over that of as many Morton runs of the faces
# (info --fit-cuts), at most these ratios at these cuts, in core and out of core.
BOX_CUTS = {12: 1.0, 100: 1.0, 1000: 0.5}
# The top of the tree (the last clusters merged by the least increase of the fit, `--top`): the
# fit (sum of area x eFit) of its cuts over that of eq. 84's order to the root (`--top 0`), at most
# these ratios; and the balance of a cut of 100: how many of its clusters hold less than 1% of the
# average cluster's area (`small_clusters` of info --fit-cuts), at most BALANCE_TARGETS on those meshes.
TOP_CUTS = {12: 1.10, 100: 1.10, 1000: 1.05}
BALANCE_CUT = 100
BALANCE_TARGETS = {"fg_hawaii": 20}
# Every cut of the top (a truncated file keeps its first nodes): the worst fit over eq. 84's order
# and the worst boxes over the Morton runs among the cuts of 2 to 64 clusters and a sample of those
# up to 512 (where the ordered top hands over to eq. 84's costs), and how many are over the
# TOP_EVERY_FIT and TOP_EVERY_BOXES bounds (reported, not checked).
TOP_EVERY_CUTS = [*range(2, 65), 80, 100, 128, 160, 192, 224, 256, 320, 384, 512]
TOP_EVERY_FIT = 1.10
TOP_EVERY_BOXES = 1.0
INFO_CUTS = sorted(set(FIT_CUTS) | set(BOX_CUTS) | set(TOP_CUTS) | set(TOP_EVERY_CUTS))
# The subdivided dragon out of core: (subdivision levels of dragon_vrip, --memory), coherent and with
# vertices and faces shuffled. The quick run takes the 14M-face one only (about two minutes).
DRAGON_CASES_QUICK = [(2, "64M")]
DRAGON_CASES_FULL = [(2, "64M"), (3, "256M")]
# Targets of the out-of-core pipeline on 2 cores (checks in the JSON).
DRAGON_TARGETS = {
    # 55.8M faces: seconds, peak RSS under the cap, temporary peak at most the file it writes.
    3: {"seconds": 80.0, "temporary_over_file": 1.0, "faces_per_second": 0.7e6},
    2: {"faces_per_second": 0.6e6},  # 14M faces, coherent
}
DRAGON_SHUFFLED_RATIO = 2.0  # shuffled time at most twice the coherent one
# Every shared mesh of 1M faces or more, out of core under a small cap against in core: cut fits
# (sum of area x eFit) within 10%, heights within 1.25x.
CAP_QUALITY_MESHES = ["matterport_cedar_creek", "fg_hawaii"]
# and every other shared mesh that the cap takes out of core, and generated meshes of many pieces (gen
# assembly: boxes touching along stored-twice faces; gen tiled: a terrain scan in unwelded tiles with
# material groups, holes and islands), compared at every cut of the top (TOP_EVERY_CUTS and 1,000):
# at most TOP_EVERY_FIT out of core over in core.
CAP_QUALITY_SMALL_MESHES = ["cura_ultimaker_robot", "dragon_vrip", "openfoam_buildings", "turbine_blade_200k"]
CAP_QUALITY_GENERATED = [("assembly 3M", "assembly", 3_000_000), ("tiled 3M", "tiled", 3_000_000)]
# and the 14M-face dragon (gen subdivide dragon_vrip --levels 2), generated for the section
CAP_QUALITY_DRAGON_LEVELS = 2
CAP_QUALITY_CAP = "64M"
CAP_QUALITY_FIT_BOUND = 1.10
CAP_QUALITY_HEIGHT_BOUND = 1.25


def run(command):
    """Runs a command; returns (stdout, wall seconds)."""
    start = time.perf_counter()
    process = subprocess.Popen([str(c) for c in command], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    stdout, stderr = process.communicate()
    wall = time.perf_counter() - start
    if process.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} failed: {stderr.strip()}")
    return stdout, wall


class ChildCpu:
    """CPU seconds (user + system) of the children reaped since the last call: runs are
    sequential and communicate() reaps each child, so a lap around one run is that run's."""

    def __init__(self):
        self.last = self.now()

    @staticmethod
    def now():
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        return usage.ru_utime + usage.ru_stime

    def lap(self):
        now = self.now()
        lap, self.last = now - self.last, now
        return lap


CPU = ChildCpu()


TIME = "/usr/bin/time"


def run_measured(command):
    """Runs a command; returns (stdout, wall seconds, process CPU seconds, peak RSS bytes): CPU from
    wait4's rusage, the peak from /usr/bin/time (its maximum resident set size). Output goes through
    temporary files so that the child is reaped here, by wait4, and not by Popen."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err, \
            tempfile.NamedTemporaryFile("r") as peak:
        start = time.perf_counter()
        # Linux carries a process's peak RSS across exec: a child forked from this interpreter
        # reports at least the interpreter's own peak. /usr/bin/time forks the command from a small
        # process, and its %M is the command's own.
        process = subprocess.Popen([TIME, "-f", "%M", "-o", peak.name, *map(str, command)], stdout=out,
                                   stderr=err, text=True)
        _, status, usage = os.wait4(process.pid, 0)
        wall = time.perf_counter() - start
        process.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0), err.seek(0)
        stdout, stderr = out.read(), err.read()
        peak_kib = peak.read().strip().splitlines()
    if process.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} failed ({process.returncode}): {stderr.strip()}")
    CPU.lap()  # keep the children's CPU clock of the other sections in step
    return stdout, wall, usage.ru_utime + usage.ru_stime, int(peak_kib[-1]) * 1024


def run_json(command):
    CPU.lap()
    stdout, wall = run(command)
    result = json.loads(stdout)
    result["process_cpu_seconds"] = CPU.lap()
    result["process_wall_seconds"] = wall
    return result


def timed(command):
    CPU.lap()
    _, wall = run(command)
    CPU.lap()
    return wall


def repeat_runs(repeat, function):
    return [function() for _ in range(repeat)]


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def loglog_slope(points):
    """Least-squares slope of log(y) against log(x)."""
    points = [(x, y) for x, y in points if x and y and x > 0 and y > 0]
    if len(points) < 2:
        return float("nan")
    xs = [math.log(x) for x, _ in points]
    ys = [math.log(y) for _, y in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    var = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / var if var > 0 else float("nan")


def mesh_path(mesh):
    return SHARED / f"{mesh}.ply.zst"


class MeshRuns:
    """The per-mesh builds shared by several sections, run once and interleaved: per repetition
    the default metric, the Garland metric and the octree, one after the other, so that their
    ratios see the same machine load."""

    def __init__(self, args, out):
        self.args = args
        self.pictures = out / "pictures"
        self.cache = {}

    def get(self, mesh):
        if mesh in self.cache:
            return self.cache[mesh]
        path = mesh_path(mesh)
        runs = {"willmott": [], "garland": [], "octree": []}
        for repetition in range(self.args.repeat):
            # --quick runs the Garland metric once: its heights are deterministic, and its time
            # on dragon_vrip alone would take a third of the quick budget on a loaded machine.
            metrics = ("willmott", "garland") if repetition == 0 or not self.args.quick else ("willmott",)
            for metric in metrics:
                if metric == "garland" and runs["willmott"][0]["triangles"] > GARLAND_MAX_FACES:
                    continue
                command = [self.args.facetree, "build", "--json", path, "--metric", metric]
                # The first run of a picture mesh also writes its cluster file (the phases end
                # before the write; its peak RSS is left out of the memory figures).
                wrote = repetition == 0 and mesh in PICTURE_MESHES and self.args.pictures
                if wrote:
                    self.pictures.mkdir(parents=True, exist_ok=True)
                    command += ["-o", self.pictures / f"{mesh}.{metric}.fch"]
                result = run_json(command)
                result["wrote_file"] = bool(wrote)
                runs[metric].append(result)
            runs["octree"].append(run_json([self.args.facetree, "build", "--json", path, "--method", "octree"]))
        self.cache[mesh] = runs
        return runs


def cluster_seconds(result):
    """Wall seconds of the face clustering itself: hierarchy and boxes, without reading."""
    return result["seconds"]["build"] - result["seconds"]["read"]


def summarize_build(runs):
    first = runs[0]
    phases = {k: median(r["seconds"][k] for r in runs) for k in first["seconds"]}
    no_file = [r for r in runs if not r.get("wrote_file")] or runs
    return {
        "triangles": first["triangles"], "seconds": phases,
        "cluster_seconds": median(cluster_seconds(r) for r in runs),
        "process_cpu_seconds": median(r["process_cpu_seconds"] for r in runs),
        "peak_rss_bytes": max(r["peak_rss_bytes"] for r in no_file),
        "height": first["height"], "balanced_height": first["balanced_height"],
        "height_ratio": first["height_ratio"], "average_degree": first["average_degree"],
        "max_degree": first["max_degree"], "components": first["components"], "nodes": first["nodes"],
        "eigen_solves": first["eigen_solves"], "normal_shortcuts": first["normal_shortcuts"],
        "runs": len(runs),
    }


# --- sections ---------------------------------------------------------------------------------

def bench_read(args, meshes):
    rows = []
    for mesh in meshes:
        path = mesh_path(mesh)
        stats = repeat_runs(args.repeat, lambda: run_json([args.facetree, "stats", "--json", path]))
        zstd = repeat_runs(args.repeat, lambda: timed(["zstd", "-dcq", path, "-o", "/dev/null"]))
        seconds = statistics.median(s["read_seconds"] for s in stats)
        baseline = statistics.median(zstd)
        rows.append({
            "mesh": mesh, "faces": stats[0]["faces"], "input_bytes": stats[0]["input_bytes"],
            "seconds": seconds, "mb_per_second": stats[0]["input_bytes"] / seconds / 1e6,
            "faces_per_second": stats[0]["faces"] / seconds,
            "peak_rss_bytes": max(s["peak_rss_bytes"] for s in stats),
            "zstd_seconds": baseline, "ratio_to_zstd": seconds / baseline,
        })
        print(f"read      {mesh:24s} {seconds:7.3f} s  {rows[-1]['mb_per_second']:7.1f} MB/s  "
              f"{rows[-1]['faces_per_second'] / 1e6:6.2f} M faces/s  peak {rows[-1]['peak_rss_bytes'] / 2**20:6.1f} MiB  "
              f"x{rows[-1]['ratio_to_zstd']:.2f} of zstd -dc", flush=True)
    return rows


def bench_build(args, meshes, runs):
    rows = []
    for mesh in meshes:
        path = mesh_path(mesh)
        builds = runs.get(mesh)["willmott"]
        reads = repeat_runs(args.repeat, lambda: run_json([args.facetree, "stats", "--json", path]))
        row = {"mesh": mesh, "options": [], **summarize_build(builds)}
        row["read_seconds"] = statistics.median(r["read_seconds"] for r in reads)
        row["ratio_to_read"] = row["seconds"]["total"] / row["read_seconds"]
        rows.append(row)
        phases = row["seconds"]
        print(f"build     {mesh:24s} {phases['total']:7.3f} s (merge {phases['merge']:.3f}, boxes {phases['boxes']:.3f})  "
              f"peak {row['peak_rss_bytes'] / 2**20:6.1f} MiB  height {row['height']}/{row['balanced_height']} "
              f"= {row['height_ratio']:.2f}  degree {row['average_degree']:.2f}/{row['max_degree']}  "
              f"x{row['ratio_to_read']:.1f} of reading", flush=True)
    return rows


# Table 5/8 rows from the phases `build --json` reports. The eigensolver is timed inside the
# initial costs and the merge loop (sampled, merge/cost/cost.cpp), so it is a share of those two,
# shown on its own as the seed's Jacobi row is; "merge loop" excludes it.
PROFILE_ROWS = [
    ("eigen", "eigensolver (PCA)"),
    ("initial_cost", "initial edge costs + heap"),
    ("merge_loop", "merge loop: re-costing, edge lists, heap"),
    ("init", "leaf init + dual graph"),
    ("boxes", "boxes + side areas"),
    ("rest", "rest (layout, join)"),
]


def profile_phases(summary):
    s = summary["seconds"]
    total = s["build"] - s["read"]
    merge_loop = max(0.0, s["merge"] - s["eigen"])
    initial_cost = s["cost"]
    # Eigen time falls in both phases; take it out of the merge loop where it mostly is.
    if s["eigen"] > s["merge"]:
        initial_cost = max(0.0, s["cost"] - (s["eigen"] - s["merge"]))
    phases = {"eigen": s["eigen"], "initial_cost": initial_cost, "merge_loop": merge_loop,
              "init": s["init"], "boxes": s["boxes"]}
    phases["rest"] = max(0.0, total - sum(phases.values()))
    return phases, total


def bench_profile(args, runs):
    rows = []
    mesh_runs = runs.get(PROFILE_MESH)
    for metric in ("willmott", "garland"):
        if not mesh_runs[metric]:
            continue
        summary = summarize_build(mesh_runs[metric])
        phases, total = profile_phases(summary)
        row = {"mesh": PROFILE_MESH, "metric": metric, "triangles": summary["triangles"], "phases": phases,
               "total": total, "read": summary["seconds"]["read"],
               "process_cpu_seconds": summary["process_cpu_seconds"],
               "eigen_solves": summary["eigen_solves"], "normal_shortcuts": summary["normal_shortcuts"],
               "phase_labels": PROFILE_ROWS}
        rows.append(row)
        print(f"profile   {PROFILE_MESH} --metric {metric}: {total:.3f} s without reading, "
              f"{summary['eigen_solves']} PCA solves, {summary['normal_shortcuts']} normals from S", flush=True)
        for key, label in PROFILE_ROWS:
            print(f"profile     {phases[key]:8.3f} s {100 * phases[key] / total:5.1f}%  {label}", flush=True)
    return rows


def render_picture(args, fch, png, cut):
    run([args.facetree, "render", fch, "--cut", cut, "-o", png, "--width", 480, "--height", 400])
    fch.unlink()


def bench_balance(args, meshes, runs, out):
    rows = []
    for mesh in meshes:
        mesh_runs = runs.get(mesh)
        default = summarize_build(mesh_runs["willmott"])
        row = {"mesh": mesh, "triangles": default["triangles"], "balanced_height": default["balanced_height"],
               "garland": None}
        for name in ("willmott", "garland"):
            if not mesh_runs[name]:
                continue  # over GARLAND_MAX_FACES
            s = summarize_build(mesh_runs[name])
            row[name] = {"height": s["height"], "height_ratio": s["height_ratio"],
                         "boxes_seconds": s["seconds"]["boxes"], "cluster_seconds": s["cluster_seconds"],
                         "process_cpu_seconds": s["process_cpu_seconds"], "max_degree": s["max_degree"],
                         "average_degree": s["average_degree"], "runs": s["runs"]}
        rows.append(row)
        if row["garland"] is None:
            print(f"balance   {mesh:24s} balanced {row['balanced_height']:3d}  height default {default['height']:5d} "
                  f"garland skipped (over {GARLAND_MAX_FACES} faces)", flush=True)
            continue
        garland = row["garland"]
        row["garland_over_default_height"] = garland["height"] / default["height"]
        row["garland_over_default_boxes"] = garland["boxes_seconds"] / max(default["seconds"]["boxes"], 1e-9)
        print(f"balance   {mesh:24s} balanced {row['balanced_height']:3d}  height default {default['height']:5d} "
              f"garland {garland['height']:5d} (x{row['garland_over_default_height']:.1f})  boxes "
              f"{default['seconds']['boxes']:.3f} s / {garland['boxes_seconds']:.3f} s", flush=True)

    # k of eq. 80 with the balance guard (default --balance-slack 1.5) and without it (0: pure
    # eq. 84, the seed's metric): the guard caps the height whatever k is.
    k_rows = []
    # dragon_vrip is left out of the full sweep: 24 builds of it are a tenth of the full budget.
    for mesh in (["bunny_zipper"] if args.quick else ["bunny_zipper", "turbine_blade_200k", "openfoam_buildings"]):
        path = mesh_path(mesh)
        cases = [(k, slack) for slack in (1.5, 0.0) for k in K_VALUES]
        # Interleaved per repetition (the default k included) so that the times compare.
        builds = {case: [] for case in cases}
        for _ in range(args.repeat):
            for k, slack in cases:
                builds[(k, slack)].append(run_json([args.facetree, "build", "--json", path, "--k", repr(k),
                                                    "--balance-slack", repr(slack)]))
        for k, slack in cases:
            s = summarize_build(builds[(k, slack)])
            k_rows.append({"mesh": mesh, "k": k, "balance_slack": slack, "height": s["height"],
                           "balanced_height": s["balanced_height"], "height_ratio": s["height_ratio"],
                           "boxes_seconds": s["seconds"]["boxes"], "cluster_seconds": s["cluster_seconds"],
                           "process_cpu_seconds": s["process_cpu_seconds"], "max_degree": s["max_degree"],
                           "average_degree": s["average_degree"]})
            print(f"balance   {mesh:24s} k={k:<7g} slack {slack:3.1f}  height {s['height']:5d}/{s['balanced_height']}  "
                  f"boxes {s['seconds']['boxes']:.3f} s  clustering {s['cluster_seconds']:.3f} s  "
                  f"CPU {s['process_cpu_seconds']:.3f} s", flush=True)

    pictures = []
    if args.pictures:
        for mesh in PICTURE_MESHES:
            if mesh not in meshes:
                continue
            mesh_runs = runs.get(mesh)  # writes the cluster files on its first repetition
            # The top of a hierarchy joins the mesh's components (dragon_vrip has 151, mostly
            # specks): a cut of PICTURE_CUT clusters below them, the same cut for both metrics.
            cut = PICTURE_CUT + max(mesh_runs[m][0]["components"] for m in ("willmott", "garland"))
            for metric in ("willmott", "garland"):
                fch = out / "pictures" / f"{mesh}.{metric}.fch"
                png = out / "pictures" / f"{mesh}.{metric}.png"
                if fch.exists():
                    render_picture(args, fch, png, cut)
                    pictures.append({"mesh": mesh, "metric": metric, "cut": cut, "png": str(png)})
                    print(f"balance   picture {png} (cut {cut})", flush=True)
    return {"meshes": rows, "k": k_rows, "pictures": pictures}


def scaling_point(mesh, source, s):
    """A scaling point from summarize_build of in-core `build --json` runs."""
    return {"mesh": mesh, "source": source, "memory": None, "out_of_core": False, "faces": s["triangles"],
            "cluster_seconds": s["cluster_seconds"], "process_cpu_seconds": s["process_cpu_seconds"],
            "read_seconds": s["seconds"]["read"], "peak_rss_bytes": s["peak_rss_bytes"],
            "average_degree": s["average_degree"], "max_degree": s["max_degree"], "runs": s["runs"]}


def scaling_out_of_core_point(args, size, out):
    """One capped build (`build MESH -o OUT --memory CAP --tmp DIR --json`) of a generated terrain.
    Its clustering time is the job's total less its read (bin, cells, merge, and the write, which
    computes the boxes and compresses the file); CPU and peak RSS are the process's (wait4)."""
    mesh, fch, tmp = out / f"terrain_{size}.ply", out / "scaling_out_of_core.fch", out / "scaling_tmp"
    tmp.mkdir(exist_ok=True)
    try:
        started = time.perf_counter()
        run([args.facetree, "gen", "terrain", "-n", size, "-o", mesh])
        generate_seconds = time.perf_counter() - started
        input_bytes = mesh.stat().st_size
        report = build_job(args, mesh, fch, ["--memory", SCALING_OUT_OF_CORE_CAP, "--tmp", tmp])
    finally:
        mesh.unlink(missing_ok=True)
        fch.unlink(missing_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)
    phases = report["seconds"]
    return {"mesh": f"terrain {size // 1_000_000}M", "source": "generated", "memory": SCALING_OUT_OF_CORE_CAP,
            "out_of_core": report["out_of_core"], "faces": report["triangles"],
            "cluster_seconds": phases["total"] - phases["read"], "process_cpu_seconds": report["process_cpu_seconds"],
            "read_seconds": phases["read"], "peak_rss_bytes": report["process_peak_rss_bytes"],
            "job_peak_rss_bytes": report["peak_rss_bytes"], "average_degree": None, "max_degree": None,
            "runs": 1, "phases": phases, "process_wall_seconds": report["process_wall_seconds"],
            "cells": report["cells"], "leaves": report["leaves"], "height": report["height"],
            "balanced_height": report["balanced_height"], "file_bytes": report["file_bytes"],
            "temporary_bytes_peak": report["temporary_bytes_peak"], "input_bytes": input_bytes,
            "generate_seconds": generate_seconds}


def scaling_slopes(points):
    return {"time": loglog_slope([(p["faces"], p["cluster_seconds"]) for p in points]),
            "cpu": loglog_slope([(p["faces"], p["process_cpu_seconds"]) for p in points]),
            "rss": loglog_slope([(p["faces"], p["peak_rss_bytes"]) for p in points])}


def bench_scaling(args, meshes, runs, out):
    points = [scaling_point(mesh, "shared", summarize_build(runs.get(mesh)["willmott"])) for mesh in meshes]
    for size in (SCALING_QUICK if args.quick else SCALING_FULL):
        mesh = out / f"terrain_{size}.ply"
        run([args.facetree, "gen", "terrain", "-n", size, "-o", mesh])
        builds = repeat_runs(args.repeat, lambda: run_json([args.facetree, "build", "--json", mesh]))
        mesh.unlink()
        points.append(scaling_point(f"terrain {size // 1000}k", "generated", summarize_build(builds)))
    for size in ([] if args.quick else SCALING_OUT_OF_CORE):
        points.append(scaling_out_of_core_point(args, size, out))
    points.sort(key=lambda p: p["faces"])
    for p in points:
        degree = (f"degree {p['average_degree']:.2f}/{p['max_degree']}" if p["average_degree"] is not None else
                  f"out of core under --memory {p['memory']}, 1 run: {p['cells']} cells, height "
                  f"{p['height']}/{p['balanced_height']}")
        print(f"scaling   {p['mesh']:24s} {p['faces']:9d} faces  {p['cluster_seconds']:8.3f} s  cpu "
              f"{p['process_cpu_seconds']:7.3f} s  peak {p['peak_rss_bytes'] / 2**20:7.1f} MiB  {degree}", flush=True)
    # Meshes under 10k faces are dominated by fixed costs (process start, thread pool): left out
    # of the fits, as the seed's Fig. 77 starts at 10k. The fit is over the in-core builds; the
    # out-of-core point is a different build (its RSS is bounded by the cap): slopes with it apart.
    fit = [p for p in points if p["faces"] >= 10_000 and not p["memory"]]
    slopes = scaling_slopes(fit)
    result = {"points": points, "fit": "in-core points of 10k faces and more",
              "slope_time": slopes["time"], "slope_cpu": slopes["cpu"], "slope_rss": slopes["rss"]}
    print(f"scaling   log-log slopes over {len(fit)} in-core meshes of 10k faces and more: time "
          f"{result['slope_time']:.2f}, CPU {result['slope_cpu']:.2f}, peak RSS {result['slope_rss']:.2f}", flush=True)
    if any(p["memory"] for p in points):
        result["with_out_of_core"] = scaling_slopes([p for p in points if p["faces"] >= 10_000])
        w = result["with_out_of_core"]
        print(f"scaling   with the out-of-core point: time {w['time']:.2f}, CPU {w['cpu']:.2f}, peak RSS "
              f"{w['rss']:.2f} (bounded by the cap)", flush=True)
    return result


def bench_octree(args, meshes, runs, out):
    rows = []
    for mesh in meshes:
        mesh_runs = runs.get(mesh)
        clustering, octree = mesh_runs["willmott"], mesh_runs["octree"]
        # Per repetition: the two builds ran back to back, so their ratio sees one machine load.
        wall = [cluster_seconds(c) / max(o["seconds"]["octree"], 1e-9) for c, o in zip(clustering, octree)]
        # CPU: the clustering process minus what the octree process spent outside its octree
        # (start, read, exit: the same work in both), over the octree's own CPU time.
        cpu = [(c["process_cpu_seconds"] - (o["process_cpu_seconds"] - o["cpu_seconds"]["octree"]))
               / max(o["cpu_seconds"]["octree"], 1e-9) for c, o in zip(clustering, octree)]
        first = octree[0]
        row = {"mesh": mesh, "triangles": first["triangles"],
               "cluster_seconds": median(cluster_seconds(c) for c in clustering),
               "octree_seconds": median(o["seconds"]["octree"] for o in octree),
               "octree_cpu_seconds": median(o["cpu_seconds"]["octree"] for o in octree),
               "ratio": median(wall), "ratio_cpu": median(cpu),
               "octree_nodes": first["nodes"], "octree_height": first["height"],
               "cluster_height": clustering[0]["height"], "octree_peak_rss_bytes": first["peak_rss_bytes"]}
        rows.append(row)
        print(f"octree    {mesh:24s} clustering {row['cluster_seconds']:7.3f} s  octree {row['octree_seconds']:6.3f} s  "
              f"ratio x{row['ratio']:.1f} (CPU x{row['ratio_cpu']:.1f})  heights {row['cluster_height']}/"
              f"{row['octree_height']}", flush=True)
    big = [r for r in rows if r["triangles"] >= 50_000]
    summary = {"rows": rows, "median_ratio": median(r["ratio"] for r in big),
               "median_ratio_cpu": median(r["ratio_cpu"] for r in big)}
    if big:
        print(f"octree    median ratio over meshes of 50k faces and more: x{summary['median_ratio']:.1f} "
              f"(CPU x{summary['median_ratio_cpu']:.1f}); the seed reports about 2.5", flush=True)
    if args.callgrind:
        summary["instructions"] = octree_instructions(args, CALLGRIND_MESH, out)
    return summary


def callgrind_total(args, command, out, toggle=None):
    """Instructions callgrind counts for a whole run, or within calls of `toggle` (this thread)."""
    target = out / "callgrind.out"
    options = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={target}"]
    if toggle:
        options.append(f"--toggle-collect={toggle}")
    run(options + [args.facetree] + command)
    for line in target.read_text().splitlines():
        if line.startswith("totals:"):
            target.unlink()
            return int(line.split()[1])
    raise RuntimeError(f"no totals in {target}")


def octree_instructions(args, mesh, out):
    """The octree ratio in instructions (callgrind), which machine load does not move. The box
    threads run outside buildHierarchy's call, so the clustering is the whole build process
    minus what the octree process spends outside buildOctree (start, read, exit: the same)."""
    path = mesh_path(mesh)
    build = callgrind_total(args, ["build", path], out)
    octree_all = callgrind_total(args, ["build", path, "--method", "octree"], out)
    octree = callgrind_total(args, ["build", path, "--method", "octree"], out, "facetree::buildOctree(*")
    clustering = build - (octree_all - octree)
    result = {"mesh": mesh, "clustering": clustering, "octree": octree, "ratio": clustering / octree}
    print(f"octree    {mesh}: {clustering / 1e6:.0f} M instructions clustering, {octree / 1e6:.0f} M octree: "
          f"ratio x{result['ratio']:.1f} (callgrind)", flush=True)
    return result


def bench_branching(args, meshes, tmp):
    rows, prefixes = [], []
    for mesh in meshes:
        path = mesh_path(mesh)
        for branching in (2, 4, 8):
            out = tmp / f"{mesh}.b{branching}.fch"
            run_json([args.facetree, "build", "--json", path, "-o", out, "--branching", str(branching)])
            verify = subprocess.run([args.facetree, "verify", out], capture_output=True, text=True)
            info = run_json([args.facetree, "info", "--json", out])
            size = out.stat().st_size
            rows.append({"mesh": mesh, "branching": branching, "bytes": size, "nodes": info["nodes"],
                         "height": info["height"], "info": info, "verified": verify.returncode == 0})
            print(f"branching {mesh:24s} b={branching}  {size / 1e6:8.2f} MB  {info['nodes']:8d} nodes  verify "
                  f"{'ok' if verify.returncode == 0 else 'FAILED: ' + verify.stdout.strip()}", flush=True)
            if branching == 2:
                # Truncation prefixes: 1, 4, 16, ... nodes up to the whole file.
                nodes, total = 1, info["nodes"]
                while True:
                    kept = min(nodes, total)
                    prefix = tmp / f"{mesh}.prefix.fch"
                    result = run_json([args.facetree, "truncate", "--json", out, "-o", prefix, "--nodes", kept])
                    prefixes.append({"mesh": mesh, "nodes": result["nodes"], "bytes": result["bytes"],
                                     "fraction_of_nodes": result["nodes"] / total, "fraction_of_bytes":
                                     result["bytes"] / size})
                    prefix.unlink()
                    if kept == total:
                        break
                    nodes *= 4
                print(f"branching {mesh:24s} prefixes: " + ", ".join(
                    f"{p['nodes']}: {p['bytes'] / 1e6:.2f} MB" for p in prefixes if p["mesh"] == mesh), flush=True)
            out.unlink()
    return {"sizes": rows, "prefixes": prefixes}


def bench_flat(args, tmp):
    sizes = [10_000, 40_000, 160_000] if args.quick else [10_000, 40_000, 160_000, 640_000, 1_000_000, 4_000_000]
    # The constant and Garland metrics are O(n^1.5 log n) on grids (Fig. 69; Garland's slope is
    # ~1.4 here: 4M triangles would take half an hour a run): keep them to the sizes that finish.
    unbalanced_limit = 160_000 if args.quick else 640_000
    rows = []
    for metric in ("willmott", "constant", "garland"):
        points = []
        for size in sizes:
            if metric != "willmott" and size > unbalanced_limit:
                continue
            mesh = tmp / f"grid_{size}.ply"
            if not mesh.exists():
                run([args.facetree, "gen", "grid", "-n", str(size), "-o", mesh])
            runs = repeat_runs(args.repeat, lambda: run_json(
                [args.facetree, "build", "--json", "--no-boxes", "--metric", metric, mesh]))
            seconds = statistics.median(r["seconds"]["total"] for r in runs)
            row = {"metric": metric, "triangles": runs[0]["triangles"], "seconds": seconds,
                   "process_cpu_seconds": median(r["process_cpu_seconds"] for r in runs),
                   "max_degree": runs[0]["max_degree"], "average_degree": runs[0]["average_degree"],
                   "height": runs[0]["height"], "balanced_height": runs[0]["balanced_height"]}
            rows.append(row)
            points.append((row["triangles"], seconds))
            print(f"flat      {metric:9s} {row['triangles']:9d} tris  {seconds:8.3f} s  max degree {row['max_degree']:6d}  "
                  f"height {row['height']}/{row['balanced_height']}", flush=True)
        print(f"flat      {metric:9s} log-log slope of time {loglog_slope(points):.2f}", flush=True)
    for mesh in tmp.glob("grid_*.ply"):
        mesh.unlink()
    slopes = {}
    for metric in ("willmott", "constant", "garland"):
        points = [(r["triangles"], r["seconds"]) for r in rows if r["metric"] == metric]
        slopes[metric] = loglog_slope(points)
    return {"rows": rows, "slopes": slopes}


def build_job(args, mesh, fch, options):
    """One `facetree build MESH -o FCH --json` through the job; its report with the wall, process CPU
    and peak RSS of the process as wait4 saw them."""
    stdout, wall, cpu, rss = run_measured([args.facetree, "build", mesh, "-o", fch, "--json", *options])
    report = json.loads(stdout)
    report.update(process_wall_seconds=wall, process_cpu_seconds=cpu, process_peak_rss_bytes=rss)
    return report


def cap_bytes(cap):
    return int(cap[:-1]) << {"M": 20, "G": 30}[cap[-1]]


def fit_cuts(args, fch):
    info = json.loads(run([args.facetree, "info", fch, "--json", "--fit-cuts", ",".join(map(str, INFO_CUTS))])[0])
    cuts = {int(k): v for k, v in info["fit_cuts"].items()}
    return {"height": info["height"], "balanced_height": info["balanced_height"],
            "cuts": {c: cuts[c] for c in FIT_CUTS},
            "top_cuts": {c: cuts[c] for c in TOP_CUTS},
            "every_cut": {c: cuts[c] for c in TOP_EVERY_CUTS if c in cuts},
            "box_ratio": {c: ratio(cuts[c]["sum_box_area"], cuts[c]["morton_box_area"]) for c in BOX_CUTS}}


def top_every_cut(mine, eq84):
    """The worst fit (over eq. 84's order's cut of as many clusters) and the worst boxes (over the
    Morton runs') among the top's cuts, where they are, and how many are over the bounds."""
    fits = {c: ratio(mine[c]["sum_area_fit"], eq84[c]["sum_area_fit"]) for c in mine
            if c in eq84 and eq84[c]["sum_area_fit"]}
    boxes = {c: ratio(mine[c]["sum_box_area"], mine[c]["morton_box_area"]) for c in mine}
    fits = {c: r for c, r in fits.items() if r is not None}
    boxes = {c: r for c, r in boxes.items() if r is not None}
    worst_fit = max(fits, key=fits.get, default=None)
    worst_boxes = max(boxes, key=boxes.get, default=None)
    return {"cuts": [min(mine, default=0), max(mine, default=0)], "list": sorted(fits),
            "fit": fits.get(worst_fit), "fit_cut": worst_fit,
            "fit_over": sum(r > TOP_EVERY_FIT for r in fits.values()),
            "boxes": boxes.get(worst_boxes), "boxes_cut": worst_boxes,
            "boxes_over": sum(r > TOP_EVERY_BOXES for r in boxes.values())}


def coherent(box_ratio):
    """Whether a file's cuts are at least as spatially coherent as BOX_CUTS asks."""
    return all(r is None or r <= BOX_CUTS[c] for c, r in box_ratio.items())


def ratio(a, b):
    return a / b if a is not None and b else None


# Targets of the merge in rounds (same-run ratios): whole `build -o` processes on the 2-core machine.
ROUNDS_TARGETS = {
    "dragon_vrip": {"seconds": 1.0, "seconds_one_thread": 1.8, "peak_rss_bytes": 150e6, "octree_ratio": 1.6},
    "openfoam_buildings": {"seconds": 0.5},
    "fg_hawaii": {"seconds": 4.0},
}
ROUNDS_FIT_BOUND = 1.05  # cut fits within 5% of the exact order's (or better)
# A CAD-like assembly (gen assembly): two groups of boxes far apart, touching faces stored twice.
ASSEMBLY_FACES = 331_000
ASSEMBLY_NAME = "assembly 331k"


def bench_rounds(args, meshes, out):
    """The merge in rounds against the exact greedy: time, memory, rounds, height, cut fits, the
    coherence of the top; the shared meshes and a generated assembly of parts (gen assembly)."""
    tmp = out / "rounds_tmp"
    tmp.mkdir(exist_ok=True)
    assembly = tmp / "assembly.ply"
    run([args.facetree, "gen", "assembly", "-n", ASSEMBLY_FACES, "-o", assembly])
    rows = []
    for mesh, path in [(m, mesh_path(m)) for m in meshes] + [(ASSEMBLY_NAME, assembly)]:
        files = {name: tmp / f"{mesh}.{name}.fch" for name in ("rounds", "one", "exact", "eq84")}
        variants = {"rounds": [], "one": ["--threads", "1"], "exact": ["--order", "exact"]}
        runs = {name: [] for name in (*variants, "octree")}
        for _ in range(args.repeat):
            for name, options in variants.items():
                runs[name].append(build_job(args, path, files[name], options))
            stdout, wall, cpu, rss = run_measured([args.facetree, "build", path, "--method", "octree", "--json"])
            runs["octree"].append({"process_wall_seconds": wall, "process_cpu_seconds": cpu,
                                   "process_peak_rss_bytes": rss, **json.loads(stdout)})
        # eq. 84's order to the root, once (its cuts are what the top is measured against).
        build_job(args, path, files["eq84"], ["--top", "0"])
        infos = {name: fit_cuts(args, files[name]) for name in ("rounds", "exact", "eq84")}
        top_fit = {c: ratio(infos["rounds"]["top_cuts"][c]["sum_area_fit"], infos["eq84"]["top_cuts"][c]["sum_area_fit"])
                   for c in TOP_CUTS}
        small = {name: infos[name]["top_cuts"][BALANCE_CUT]["small_clusters"] for name in ("rounds", "eq84")}
        every = top_every_cut(infos["rounds"]["every_cut"], infos["eq84"]["every_cut"])
        fits = {name: {c: v["sum_area_fit"] for c, v in infos[name]["cuts"].items()} for name in infos}
        box_ratio = {name: infos[name]["box_ratio"] for name in ("rounds", "exact")}
        same_bytes = files["rounds"].read_bytes() == files["one"].read_bytes()
        for f in files.values():
            f.unlink()

        def summary(name):
            r = runs[name]
            return {"wall_seconds": median(x["process_wall_seconds"] for x in r),
                    "cpu_seconds": median(x["process_cpu_seconds"] for x in r),
                    "peak_rss_bytes": max(x["process_peak_rss_bytes"] for x in r),
                    "phases": {k: median(x["seconds"][k] for x in r) for k in r[0]["seconds"]}}

        row = {"mesh": mesh, "triangles": runs["rounds"][0]["triangles"],
               **{name: summary(name) for name in runs},
               "round_count": runs["rounds"][0]["rounds"], "height": runs["rounds"][0]["height"],
               "exact_height": runs["exact"][0]["height"],
               "balanced_height": runs["rounds"][0]["balanced_height"],
               "fit": fits, "fit_ratio": {c: ratio(fits["rounds"].get(c), fits["exact"].get(c))
                                          for c in FIT_CUTS},
               "box_ratio": box_ratio,
               "top_fit_ratio": top_fit, "small_clusters": small, "top_every_cut": every,
               "same_bytes_threads_1_and_default": same_bytes}
        # Same-run ratios, median of the per-repetition ratios.
        row["ratio_to_exact"] = median(a["process_wall_seconds"] / b["process_wall_seconds"]
                                       for a, b in zip(runs["rounds"], runs["exact"]))
        row["ratio_to_octree"] = median(a["process_wall_seconds"] / b["process_wall_seconds"]
                                        for a, b in zip(runs["rounds"], runs["octree"]))
        checks = {}
        target = ROUNDS_TARGETS.get(mesh, {})
        if "seconds" in target:
            checks["seconds"] = row["rounds"]["wall_seconds"] <= target["seconds"]
        if "seconds_one_thread" in target:
            checks["seconds_one_thread"] = row["one"]["wall_seconds"] <= target["seconds_one_thread"]
        if "peak_rss_bytes" in target:
            checks["peak_rss_bytes"] = row["rounds"]["peak_rss_bytes"] <= target["peak_rss_bytes"]
        if "octree_ratio" in target:
            checks["octree_ratio"] = row["ratio_to_octree"] <= target["octree_ratio"]
        checks["height"] = row["height"] <= 2 * row["balanced_height"]
        checks["fit"] = all(r is None or r <= ROUNDS_FIT_BOUND for r in row["fit_ratio"].values())
        checks["coherence"] = coherent(box_ratio["rounds"]) and coherent(box_ratio["exact"])
        checks["top_fit"] = all(r is None or r <= TOP_CUTS[c] for c, r in top_fit.items())
        if mesh in BALANCE_TARGETS:
            checks["balance"] = small["rounds"] <= BALANCE_TARGETS[mesh]
        checks["same_bytes"] = same_bytes
        row["targets"] = target
        row["checks"] = checks
        rows.append(row)
        phases = row["rounds"]["phases"]
        fit_text = " ".join(f"{c}:{r:.3f}" for c, r in row["fit_ratio"].items() if r is not None)
        fit_text += "  boxes/Morton " + " ".join(f"{c}:{r:.2f}" for c, r in box_ratio["rounds"].items()
                                                 if r is not None)
        fit_text += "  top/eq.84 " + " ".join(f"{c}:{r:.2f}" for c, r in top_fit.items() if r is not None)
        fit_text += f"  small@{BALANCE_CUT} {small['rounds']} (eq.84 {small['eq84']})"
        if every["fit"] is not None:
            fit_text += (f"  cuts {every['cuts'][0]}-{every['cuts'][1]}: fit worst {every['fit']:.2f} at {every['fit_cut']}, {every['fit_over']} over "
                         f"{TOP_EVERY_FIT}; boxes worst {every['boxes']:.2f} at {every['boxes_cut']}, "
                         f"{every['boxes_over']} over {TOP_EVERY_BOXES}")
        failed = [k for k, ok in checks.items() if not ok]
        print(f"rounds    {mesh:24s} {row['rounds']['wall_seconds']:6.2f} s (1 thread {row['one']['wall_seconds']:.2f}, "
              f"exact {row['exact']['wall_seconds']:.2f}, octree {row['octree']['wall_seconds']:.2f}; init "
              f"{phases['init']:.2f} cost {phases['cost']:.2f} merge {phases['merge']:.2f} boxes {phases['boxes']:.2f} "
              f"write {phases['write']:.2f})  {row['round_count']} rounds  peak {row['rounds']['peak_rss_bytes'] / 2**20:.0f} MiB  "
              f"height {row['height']}/{row['balanced_height']}  fit/exact {fit_text}  "
              f"x{row['ratio_to_exact']:.2f} of exact, x{row['ratio_to_octree']:.2f} of octree"
              f"{'  missed: ' + ', '.join(failed) if failed else ''}", flush=True)
    assembly.unlink()
    return rows


def bench_dragons(args, out, tmp, fch):
    """The subdivided dragon built out of core, coherent and shuffled, against the pipeline's targets:
    one run per case (the largest takes minutes), each its own process (wall, CPU and peak RSS from
    wait4), the job's phases, temporary peak and file size."""
    rows = []
    for levels, cap in DRAGON_CASES_QUICK if args.quick else DRAGON_CASES_FULL:
        for order in ("coherent", "shuffled"):
            mesh = out / f"outofcore_dragon{levels}_{order}.ply"
            shuffle = ["--shuffle-vertices", "--shuffle-faces"] if order == "shuffled" else []
            run([args.facetree, "gen", "subdivide", mesh_path("dragon_vrip"), "--levels", str(levels), "-o", mesh,
                 *shuffle])
            report = build_job(args, mesh, fch, ["--memory", cap, "--tmp", tmp])
            mesh.unlink()
            fch.unlink(missing_ok=True)
            row = {"levels": levels, "input": order, "memory": cap, "triangles": report["triangles"],
                   "seconds": report["process_wall_seconds"], "process_cpu_seconds": report["process_cpu_seconds"],
                   "cpu_use": report["process_cpu_seconds"] / report["process_wall_seconds"],
                   "phases": report["seconds"], "peak_rss_bytes": report["process_peak_rss_bytes"],
                   "temporary_bytes_peak": report["temporary_bytes_peak"], "file_bytes": report["file_bytes"],
                   "cells": report["cells"], "height": report["height"],
                   "balanced_height": report["balanced_height"]}
            row["faces_per_second"] = row["triangles"] / row["seconds"]
            row["temporary_over_file"] = row["temporary_bytes_peak"] / row["file_bytes"]
            target = DRAGON_TARGETS.get(levels, {})
            checks = {"under_cap": row["peak_rss_bytes"] <= cap_bytes(cap)}
            if order == "coherent":
                if "seconds" in target:
                    checks["seconds"] = row["seconds"] <= target["seconds"]
                if "faces_per_second" in target:
                    checks["faces_per_second"] = row["faces_per_second"] >= target["faces_per_second"]
                if "temporary_over_file" in target:
                    checks["temporary_over_file"] = row["temporary_over_file"] <= target["temporary_over_file"]
            else:
                coherent = next(r for r in rows if r["levels"] == levels and r["input"] == "coherent")
                row["over_coherent"] = row["seconds"] / coherent["seconds"]
                checks["over_coherent"] = row["over_coherent"] <= DRAGON_SHUFFLED_RATIO
            row["checks"] = checks
            rows.append(row)
            phases = " ".join(f"{k} {v:.1f}" for k, v in row["phases"].items() if k != "total")
            print(f"outofcore dragon {row['triangles'] / 1e6:.1f}M {order:8s} --memory {cap:5s} {row['seconds']:7.1f} s "
                  f"({row['faces_per_second'] / 1e6:.2f}M faces/s, CPU {row['cpu_use'] * 100:.0f}%; {phases})  peak "
                  f"{row['peak_rss_bytes'] / 2**20:.1f} MiB  tmp {row['temporary_bytes_peak'] / 1e6:.0f} MB "
                  f"({row['temporary_over_file']:.2f}x the file, {row['file_bytes'] / 1e6:.0f} MB)  checks " +
                  " ".join(f"{k}:{'ok' if v else 'MISSED'}" for k, v in checks.items()), flush=True)
    return rows


def bench_cap_quality(args, tmp, fch):
    """Every shared mesh of 1M faces or more, and the 14M-face dragon, built in core and out of core under
    CAP_QUALITY_CAP: cut fits (sum of area x eFit at FIT_CUTS clusters), heights and the coherence of the
    top, out of core over in core."""
    rows = []
    dragon = tmp / "cap_quality_dragon.ply"
    run([args.facetree, "gen", "subdivide", mesh_path("dragon_vrip"), "--levels", str(CAP_QUALITY_DRAGON_LEVELS),
         "-o", dragon])
    generated = []
    for name, kind, faces in CAP_QUALITY_GENERATED:
        path = tmp / f"cap_quality_{kind}.ply"
        run([args.facetree, "gen", kind, "-n", faces, "-o", path])
        generated.append((name, path))
    meshes = [(n, mesh_path(n)) for n in CAP_QUALITY_MESHES + CAP_QUALITY_SMALL_MESHES] + generated
    for name, path in meshes + [("dragon 14M", dragon)]:
        results = {}
        for label, cap in (("in core", IN_CORE_CAP), ("out of core", CAP_QUALITY_CAP)):
            report = build_job(args, path, fch, ["--memory", cap, "--tmp", tmp])
            results[label] = {"out_of_core": report["out_of_core"], "seconds": report["process_wall_seconds"],
                              **fit_cuts(args, fch)}
        fch.unlink(missing_ok=True)
        inside, outside = results["in core"], results["out of core"]
        row = {"mesh": name, "memory": CAP_QUALITY_CAP, "in_core": inside, "out_of_core": outside,
               "height_ratio": outside["height"] / inside["height"],
               "fit_ratio": {n: ratio(outside["cuts"][n]["sum_area_fit"], inside["cuts"][n]["sum_area_fit"])
                             for n in inside["cuts"]},
               "box_ratio": {"in_core": inside["box_ratio"], "out_of_core": outside["box_ratio"]}}
        # The top's every-cut measure, with the in-core build in place of eq. 84's order.
        row["every_cut"] = top_every_cut({**outside["every_cut"], 1000: outside["cuts"][1000]},
                                         {**inside["every_cut"], 1000: inside["cuts"][1000]})
        row["checks"] = {"forced_out_of_core": outside["out_of_core"] and not inside["out_of_core"],
                         "fit": all(r is not None and r <= CAP_QUALITY_FIT_BOUND for r in row["fit_ratio"].values()),
                         "every_cut": row["every_cut"]["fit_over"] == 0,
                         "height": row["height_ratio"] <= CAP_QUALITY_HEIGHT_BOUND,
                         "coherence": coherent(inside["box_ratio"]) and coherent(outside["box_ratio"])}
        rows.append(row)
        print(f"outofcore quality {name:24s} --memory {CAP_QUALITY_CAP} / in core: height "
              f"{outside['height']}/{inside['height']} ({row['height_ratio']:.3f})  sum area x eFit " +
              "  ".join(f"{n}: {r:.3f}" for n, r in row["fit_ratio"].items()) +
              f"  every cut: {row['every_cut']['fit_over']} of {len(row['every_cut']['list'])} over "
              f"{TOP_EVERY_FIT}, worst {row['every_cut']['fit'] or 0:.2f} at {row['every_cut']['fit_cut']}"
              "  checks " +
              " ".join(f"{k}:{'ok' if v else 'MISSED'}" for k, v in row["checks"].items()), flush=True)
    dragon.unlink()
    for _, path in generated:
        path.unlink()
    return rows


def bench_outofcore(args, out):
    """The out-of-core build against the in-core one, cost and quality."""
    started, load_start = time.time(), os.getloadavg()
    # One run per case, in the full run too: the trees are deterministic, times carry the machine's
    # load (process CPU times less so), and the 8 builds of 10M faces take 70-180 CPU seconds each
    # (measured): three runs of each would take some 40 minutes of the hour alone.
    repeat = 1
    tmp = out / "outofcore_tmp"
    tmp.mkdir(exist_ok=True)
    fch = out / "outofcore.fch"
    faces = OUT_OF_CORE_FACES_QUICK if args.quick else OUT_OF_CORE_FACES_FULL
    rows = []
    for order in ("coherent", "shuffled"):
        mesh = out / f"outofcore_terrain_{order}.ply"
        shuffle = ["--shuffle-vertices", "--shuffle-faces"] if order == "shuffled" else []
        run([args.facetree, "gen", "terrain", "-n", faces, "-o", mesh, *shuffle])
        for cap in OUT_OF_CORE_CAPS:
            options = ["--memory", cap or IN_CORE_CAP, "--tmp", tmp]
            runs = [build_job(args, mesh, fch, options) for _ in range(repeat)]
            first = runs[0]
            row = {"mesh": f"terrain {faces / 1e6:g}M", "input": order, "memory": cap,
                   "triangles": first["triangles"], "out_of_core": first["out_of_core"],
                   "seconds": median(r["process_wall_seconds"] for r in runs),
                   "process_cpu_seconds": median(r["process_cpu_seconds"] for r in runs),
                   "phases": {k: median(r["seconds"][k] for r in runs) for k in first["seconds"]},
                   "peak_rss_bytes": max(r["peak_rss_bytes"] for r in runs),
                   "process_peak_rss_bytes": max(r["process_peak_rss_bytes"] for r in runs),
                   "peak_rss_after": first["peak_rss_after"],
                   "temporary_bytes_peak": first["temporary_bytes_peak"], "file_bytes": first["file_bytes"],
                   "cells": first["cells"], "leaves": first["leaves"], "height": first["height"],
                   "balanced_height": first["balanced_height"], "runs": len(runs)}
            row["under_cap"] = cap is None or row["process_peak_rss_bytes"] <= cap_bytes(cap)
            rows.append(row)
            print(f"outofcore {row['mesh']:12s} {order:8s} {cap or 'in core':8s} {row['seconds']:8.2f} s  cpu "
                  f"{row['process_cpu_seconds']:8.2f} s  peak {row['process_peak_rss_bytes'] / 2**20:7.1f} MiB "
                  f"(job {row['peak_rss_bytes'] / 2**20:.1f})  tmp {row['temporary_bytes_peak'] / 1e6:7.1f} MB  "
                  f"file {row['file_bytes'] / 1e6:7.1f} MB  cells {row['cells']}  leaves {row['leaves']}  "
                  f"height {row['height']}/{row['balanced_height']}", flush=True)
        fch.unlink(missing_ok=True)
        mesh.unlink()
    for row in rows:
        base = next(r for r in rows if r["input"] == row["input"] and r["memory"] is None)
        row["ratio"] = {key: ratio(row[key], base[key]) for key in
                        ("seconds", "process_cpu_seconds", "process_peak_rss_bytes", "file_bytes", "height")}

    dragons = bench_dragons(args, out, tmp, fch)
    cap_quality = bench_cap_quality(args, tmp, fch)

    quality = []
    for name, kind, generated in QUALITY_MESHES:
        if generated:
            mesh = out / "outofcore_quality.ply"
            run([args.facetree, "gen", kind, "-n", generated, "-o", mesh])
        else:
            mesh = mesh_path(name)
        builds = [(None, ["--memory", IN_CORE_CAP])]
        builds += [(n, ["--memory", IN_CORE_CAP, "--cell-faces", n, "--tmp", tmp]) for n in QUALITY_CELL_FACES]
        for cell_faces, options in builds:
            report = build_job(args, mesh, fch, options)
            fits = fit_cuts(args, fch)
            row = {"mesh": name, "triangles": report["triangles"], "cell_faces": cell_faces,
                   "out_of_core": report["out_of_core"], "cells": report["cells"], "leaves": report["leaves"],
                   "seconds": report["process_wall_seconds"], "height": fits["height"],
                   "balanced_height": fits["balanced_height"], "cuts": fits["cuts"]}
            quality.append(row)
            print(f"outofcore quality {name:12s} {'in core' if cell_faces is None else f'cells of {cell_faces}':16s} "
                  f"height {row['height']}/{row['balanced_height']}  " + "  ".join(
                      f"{n}: {c['clusters']} clusters sum eFit {c['sum_fit']:.4g} sum A*eFit {c['sum_area_fit']:.4g}"
                      for n, c in row["cuts"].items()), flush=True)
        fch.unlink(missing_ok=True)
        if generated:
            mesh.unlink()
    for row in quality:
        base = next(r for r in quality if r["mesh"] == row["mesh"] and r["cell_faces"] is None)
        row["ratio"] = {"height": ratio(row["height"], base["height"]),
                        "sum_fit": {n: ratio(c["sum_fit"], base["cuts"][n]["sum_fit"]) for n, c in row["cuts"].items()},
                        "sum_area_fit": {n: ratio(c["sum_area_fit"], base["cuts"][n]["sum_area_fit"])
                                         for n, c in row["cuts"].items()}}
        if row["cell_faces"] == min(QUALITY_CELL_FACES):
            row["checks"] = {"fit": all(r is not None and r <= QUALITY_SMALL_CELLS_FIT_BOUND
                                        for r in row["ratio"]["sum_area_fit"].values())}
        if row["cell_faces"] is not None:
            print(f"outofcore quality {row['mesh']:12s} cells of {row['cell_faces']}: OOC / in core: height "
                  f"{row['ratio']['height']:.3f}  " + "  ".join(
                      f"{n}: sum eFit {row['ratio']['sum_fit'][n]:.3f} sum A*eFit {row['ratio']['sum_area_fit'][n]:.3f}"
                      for n in row["cuts"]), flush=True)
    shutil.rmtree(tmp, ignore_errors=True)
    return {"faces": faces, "in_core_cap": IN_CORE_CAP, "repeat": repeat, "rows": rows, "dragons": dragons,
            "cap_quality": cap_quality, "quality": quality,
            "fit_cuts": FIT_CUTS, "box_cuts": BOX_CUTS, "date": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(started)),
            "load_average_start": load_start, "load_average_end": os.getloadavg(),
            "wall_seconds": time.time() - started}


SECTIONS = ["read", "build", "profile", "balance", "scaling", "octree", "branching", "flat", "rounds", "outofcore",
            "python", "queries", "speed", "format", "tiles"]


PYTHON_BUILD = r"""
import json, sys, time
import numpy as np
import facetree

def status(field):
    with open("/proc/self/status") as lines:
        return next(int(line.split()[1]) * 1024 for line in lines if line.startswith(field))

path, runs, dtypes = sys.argv[1], int(sys.argv[2]), sys.argv[3]
vertices, faces, _ = facetree.read_mesh(path)
if dtypes == "wide":
    vertices, faces = vertices.astype(np.float64), faces.astype(np.int64)
for _ in range(runs):
    with open("/proc/self/clear_refs", "w") as clear:
        clear.write("5")  # resets VmHWM, the peak resident set
    base = status("VmRSS:")
    start, cpu_start = time.perf_counter(), time.process_time()
    h = facetree.build(vertices, faces)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    print(json.dumps({"seconds": seconds, "cpu_seconds": cpu, "rss_base": base, "rss_peak": status("VmHWM:"), "nodes": len(h),
                      "copied": h.report["input_copied"]}), flush=True)
    del h
"""


# Speed against an earlier build (--baseline-facetree), alternating runs in one invocation: whole
# `build -o` processes, medians of wall and CPU; the ratio new / baseline at most SPEED_BOUND.
SPEED_BOUND = 1.10
SPEED_CASES_FULL = [("dragon_vrip in core", 0, [], 7), ("14M-face dragon at 64M", 2, ["--memory", "64M"], 5)]
SPEED_CASES_QUICK = [("dragon_vrip in core", 0, [], 3)]



# Queries (issue targets): Embree peer on dragon_vrip at most this many times its time, closest
# hits, 1M camera and 1M random rays, one thread and two; on every shared mesh at least this share
# of rays on the same triangle as Embree's, and every t within 1e-5 relative.
QUERY_PREFIXES = (0.01, 0.1, 1.0)
QUERY_EMBREE_RATIO = 4.0
QUERY_EMBREE_TARGET = 2.5
QUERY_READER_OVER_MEMORY = 1.2
QUERY_SAME_TRIANGLE = 0.9999
QUERY_T_RELATIVE = 1e-5
QUERY_ROUNDS = 2  # turns of the reader, Python and the file in memory alone
QUERY_DRAGON56 = (3, "256M")  # gen subdivide dragon_vrip --levels 3, read under this cap


# A measurement's best over rounds: the least of each time ("..._seconds", or Python's pair of them)
# and the most of each rate ("..._per_second"); other values as the first round has them.
def best_round(runs):
    first = runs[0]
    if isinstance(first, dict):
        return {k: best_round([r[k] for r in runs]) if isinstance(v, (dict, list)) else
                (min(r[k] for r in runs) if k.endswith("_seconds") else
                 max(r[k] for r in runs) if k.endswith("per_second") else v)
                for k, v in first.items()}
    if isinstance(first, list):  # Python's (closest, any) seconds
        return [min(r[i] for r in runs) for i in range(len(first))]
    return first


def query_bench_binary(args):
    binary = pathlib.Path(args.facetree).resolve().parent.parent / "tests" / "query" / "query_bench"
    if not binary.exists():
        raise RuntimeError(f"{binary} is missing: configure with -DFACETREE_QUERY_BENCH=ON (scripts/bench does)")
    return binary


def query_run(args, fch, *options):
    stdout, _ = run([query_bench_binary(args), fch, *options])
    return json.loads(stdout)


# The saved rays through facetree.open(FILE) (the default cap), intersect and occluded, the median of
# three calls after one that builds the reader's query index (query_bench's estimate too): (closest,
# any) seconds per kind of ray.
PYTHON_QUERIES = r"""
import sys, time, numpy as np, facetree
path, prefix, threads = sys.argv[1], sys.argv[2], int(sys.argv[3])
f = facetree.open(path)
out = {}
for kind in ("camera", "random"):
    rays = np.fromfile(prefix + "." + kind, dtype=np.float32).reshape(-1, 6)
    o, d = np.ascontiguousarray(rays[:, :3]), np.ascontiguousarray(rays[:, 3:])
    f.intersect(o[:1024], d[:1024], threads=threads)
    times = []
    for call in (f.intersect, f.occluded):
        runs = []
        for _ in range(3):
            start = time.perf_counter()
            call(o, d, threads=threads)
            runs.append(time.perf_counter() - start)
        times.append(sorted(runs)[1])
    out[kind] = times
boxes = np.fromfile(prefix + ".boxes", dtype=np.float32).reshape(-1, 10)
x, y, z, w = (boxes[:, 6 + k].astype(np.float64) for k in range(4))
axes = np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], 1),
                 np.stack([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)], 1),
                 np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], 1)], 2)
points = np.fromfile(prefix + ".points", dtype=np.float32).reshape(-1, 3)
lo, hi = boxes[:, :3] - boxes[:, 3:6], boxes[:, :3] + boxes[:, 3:6]
for name, call in (("boxes", lambda: f.overlap_oriented(boxes[:, :3], boxes[:, 3:6], axes.astype(np.float32),
                                                        threads=threads)),
                   ("aligned", lambda: f.overlap(lo, hi, threads=threads)),
                   ("nearest", lambda: f.nearest(points, threads=threads))):
    runs = []
    for _ in range(3):
        start = time.perf_counter()
        call()
        runs.append(time.perf_counter() - start)
    out[name + "_per_second"] = (len(points) if name == "nearest" else len(boxes)) / sorted(runs)[1]
print(__import__("json").dumps(out))
"""


def query_python(args, fch, prefix, threads):
    build_dir = pathlib.Path(args.facetree).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(build_dir / "python"))
    stdout = subprocess.run([sys.executable, "-c", PYTHON_QUERIES, str(fch), str(prefix), str(threads)],
                            env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(stdout)


def bench_queries(args, meshes, out):
    tmp = out / "queries"
    tmp.mkdir(exist_ok=True)
    rays, queries = (1 << 13, 1 << 11) if args.quick else (1 << 16, 1 << 13)
    files = {}
    experiment = []
    for mesh in meshes:
        for b in (2, 4, 8):
            fch = files[(mesh, b)] = tmp / f"{mesh}-b{b}.fch"
            run([args.facetree, "build", mesh_path(mesh), "-o", fch, "--branching", b])
            for prefix in QUERY_PREFIXES:
                r = query_run(args, fch, "--prefix", prefix, "--rays", rays, "--queries", queries, "--threads", 1,
                              "--repeat", 1)
                experiment.append({"mesh": mesh, "branching": b, "prefix": prefix, **r})
    # The best b for each kind of query: the highest median over the meshes of its rate against
    # b = 2's on the same mesh, whole files.
    kinds = {"camera": ("camera", "rays_per_second"), "random": ("random", "rays_per_second"),
             "boxes": ("boxes", "queries_per_second"), "nearest": ("nearest", "queries_per_second")}
    best = {}
    for kind, (key, rate) in kinds.items():
        relative = {b: median([r[key][rate] / next(q[key][rate] for q in experiment if q["mesh"] == r["mesh"]
                                                    and q["branching"] == 2 and q["prefix"] == 1.0)
                               for r in experiment if r["branching"] == b and r["prefix"] == 1.0])
                    for b in (2, 4, 8)}
        best[kind] = {"branching": max(relative, key=relative.get), "rate_against_b2": relative}
    b = best["camera"]["branching"]
    # The same hits as Embree's on every mesh, at the best b for camera rays.
    agreement = []
    for mesh in meshes:
        r = query_run(args, files[(mesh, b)], "--embree", "--only", "rays", "--rays", rays * 4, "--threads", 2,
                      "--repeat", 1)
        agreement.append({"mesh": mesh, **r})
    # Speed against Embree on dragon_vrip, 1M rays of each kind, one thread and two.
    speed = []
    dragon = files.get(("dragon_vrip", b))
    if dragon:
        for threads in (1, 2):
            # 16,384 boxes and points: Python's calls against the file in memory's, at least 0.1 s each
            r = query_run(args, dragon, "--embree", "--rays", 1 << 20, "--queries", 1 << 14, "--threads", threads,
                          "--repeat", args.repeat, "--save-rays", tmp / "rays")
            # The same rays through the lazy reader (its default cap) and through Python's open(), and
            # the file in memory alone, without Embree in its process (which slows it by 5-15%): the
            # baseline of the reader and Python, each timed in a process of its own. The three take
            # turns, QUERY_ROUNDS times, and each keeps its best round: a burst of the machine's
            # noise falls on one round of one of them, not on the ratio.
            rounds = [(query_run(args, dragon, "--only", "rays", "--threads", threads,
                                 "--reader-memory", cap_bytes("4G"), "--load-rays", tmp / "rays"),
                       query_python(args, dragon, tmp / "rays", threads),
                       query_run(args, dragon, "--rays", 1 << 20, "--queries", 1 << 14, "--threads", threads,
                                 "--repeat", args.repeat)) for _ in range(QUERY_ROUNDS)]
            reader_run, py, alone = (best_round([round[i] for round in rounds]) for i in range(3))
            for k in ("camera", "random"):
                r[k]["reader_closest_seconds"] = reader_run[k]["closest_seconds"]
                r[k]["reader_any_seconds"] = reader_run[k]["any_seconds"]
                r[k]["python_closest_seconds"], r[k]["python_any_seconds"] = py[k]
                for path in ("reader", "python"):
                    r[k][f"{path}_closest_ratio"] = r[k][f"{path}_closest_seconds"] / r[k]["embree_closest_seconds"]
                    r[k][f"{path}_any_ratio"] = r[k][f"{path}_any_seconds"] / r[k]["embree_any_seconds"]
            for k in ("boxes", "nearest"):  # Python's rate over the file in memory's, the same queries
                r[k]["python_queries_per_second"] = py[f"{k}_per_second"]
                r[k]["python_over_memory_time"] = r[k]["queries_per_second"] / py[f"{k}_per_second"]
            r["alone"] = {k: alone[k] for k in ("camera", "random", "boxes", "aligned", "nearest")}
            r["over_memory_alone"] = {  # each path's time over the file in memory's alone, the same queries
                **{f"{path}_{hit}_{k}": r[k][f"{path}_{hit}_seconds"] / alone[k][f"{hit}_seconds"]
                   for path in ("reader", "python") for hit in ("closest", "any") for k in ("camera", "random")},
                **{f"python_{k}": alone[k]["queries_per_second"] / py[f"{k}_per_second"]
                   for k in ("boxes", "aligned", "nearest")}}
            speed.append(r)
    # Rays through the lazy reader on the 56M-face dragon's file (full run).
    reader = None
    if not args.quick:
        levels, cap = QUERY_DRAGON56
        mesh, fch = tmp / "dragon56.ply", tmp / "dragon56.fch"
        run([args.facetree, "gen", "subdivide", mesh_path("dragon_vrip"), "--levels", levels, "-o", mesh])
        run([args.facetree, "build", mesh, "-o", fch, "--memory", cap, "--branching", b])
        mesh.unlink()
        stdout, wall, cpu, peak = run_measured([query_bench_binary(args), fch, "--reader-memory", cap_bytes(cap),
                                                "--only", "rays", "--rays", 1 << 20, "--threads", 2, "--repeat", 1])
        reader = {**json.loads(stdout), "cap": cap, "peak_rss_bytes": peak, "wall_seconds": wall,
                  "cpu_seconds": cpu, "file_bytes": fch.stat().st_size}
        fch.unlink()
    for fch in files.values():
        fch.unlink()
    checks = {
        "same_triangle_every_mesh": all(a[k]["same_triangle"] >= QUERY_SAME_TRIANGLE
                                        for a in agreement for k in ("camera", "random")),
        "t_within_1e-5_every_mesh": all(a[k]["t_outside_1e-5"] == 0 for a in agreement for k in ("camera", "random")),
        # where a t differs by more, whether Embree's is the one further from the plane's exact t
        "t_differences_embree_rounding": all(a[k]["t_outside_1e-5"] == a[k]["t_outside_1e-5_embree_further_from_exact"]
                                             for a in agreement for k in ("camera", "random")),
        # where the two differ (another triangle, or t by more than 1e-5), whether facetree's answer is the
        # exact one: the true nearest of the two triangles by a long-double test, or the t nearer the plane's
        "facetree_exact_where_they_differ": all(
            a[k].get("different_triangle_facetree_exact", -1) == a[k]["different_triangle"]
            and a[k].get("t_outside_1e-5_facetree_exact", -1) == a[k]["t_outside_1e-5"]
            for a in agreement for k in ("camera", "random")),
        "facetree_t_within_1e-6_of_exact": all(a[k]["facetree_worst_t_against_exact"] <= 1e-6
                                               for a in agreement for k in ("camera", "random")),
        "closest_within_4x_embree": bool(speed) and all(r[k]["closest_ratio"] <= QUERY_EMBREE_RATIO
                                                        for r in speed for k in ("camera", "random")),
        # the issue's bound: closest hits within 2.5x Embree in memory, through the reader and from Python,
        # and the reader within 1.2x the file in memory when the file fits its cap
        "closest_within_2.5x_embree_every_path": bool(speed) and all(
            r[k][f"{p}closest_ratio"] <= QUERY_EMBREE_TARGET for r in speed for k in ("camera", "random")
            for p in ("", "reader_", "python_")),
        "python_boxes_nearest_within_1.2x_memory": bool(speed) and all(
            r[k]["python_over_memory_time"] <= QUERY_READER_OVER_MEMORY for r in speed for k in ("boxes", "nearest")),
        # the issue's second bound against the file in memory timed alone: the reader's and Python's
        # closest and any hits (intersect, occluded), and Python's overlap (oriented and along the
        # axes) and nearest points
        "reader_python_within_1.2x_memory_alone": bool(speed) and all(
            v <= QUERY_READER_OVER_MEMORY for r in speed for v in r["over_memory_alone"].values()),
        "reader_within_1.2x_memory": bool(speed) and all(
            r[k]["reader_closest_seconds"] <= QUERY_READER_OVER_MEMORY * r[k]["closest_seconds"]
            for r in speed for k in ("camera", "random")),
    }
    if reader:
        # the whole process, index, reader and the benchmark's batch of rays, under the reader's cap
        checks["reader_peak_within_cap"] = reader["peak_rss_bytes"] <= cap_bytes(reader["cap"])
    result = {"date": time.strftime("%Y-%m-%d %H:%M"), "rays": rays, "queries": queries, "experiment": experiment,
              "best": best, "embree_branching": b,
              "agreement": agreement, "speed": speed, "reader": reader, "checks": checks}
    print("queries: best b", {k: v["branching"] for k, v in best.items()}, "checks", checks)
    for r in speed:
        print(f"  dragon_vrip {r['threads']} thread(s), closest hit over Embree's time, camera / random: in memory "
              f"{r['camera']['closest_ratio']:.2f} / {r['random']['closest_ratio']:.2f}, reader "
              f"{r['camera']['reader_closest_ratio']:.2f} / {r['random']['reader_closest_ratio']:.2f}, Python "
              f"{r['camera']['python_closest_ratio']:.2f} / {r['random']['python_closest_ratio']:.2f}; Python's "
              f"boxes and nearest points over the file in memory's time {r['boxes']['python_over_memory_time']:.2f} / "
              f"{r['nearest']['python_over_memory_time']:.2f}; "
              f"Embree build {r['embree_build_seconds']:.2f} s")
        print(f"    over the file in memory alone: " +
              ", ".join(f"{k} {v:.2f}" for k, v in r["over_memory_alone"].items()))
    return result


def bench_speed(args, out):
    if not args.baseline_facetree:
        print("speed     skipped: no --baseline-facetree", flush=True)
        return {"skipped": "no --baseline-facetree"}
    rows = []
    for name, levels, options, repeat in SPEED_CASES_QUICK if args.quick else SPEED_CASES_FULL:
        mesh = mesh_path("dragon_vrip")
        if levels:
            mesh = out / f"speed_dragon{levels}.ply"
            run([args.facetree, "gen", "subdivide", mesh_path("dragon_vrip"), "--levels", str(levels), "-o", mesh])
        samples = {"baseline": [], "new": []}
        for _ in range(repeat):
            for which, binary in (("baseline", args.baseline_facetree), ("new", args.facetree)):
                fch = out / f"speed_{which}.fch"
                _, wall, cpu, rss = run_measured([binary, "build", mesh, "-o", fch, *options])
                samples[which].append({"seconds": wall, "cpu_seconds": cpu, "peak_rss_bytes": rss})
                fch.unlink(missing_ok=True)
        if levels:
            mesh.unlink()
        row = {"case": name, "runs": repeat}
        for which, runs in samples.items():
            row[which] = {k: median(r[k] for r in runs) for k in ("seconds", "cpu_seconds", "peak_rss_bytes")}
        row["wall_ratio"] = row["new"]["seconds"] / row["baseline"]["seconds"]
        row["cpu_ratio"] = row["new"]["cpu_seconds"] / row["baseline"]["cpu_seconds"]
        row["met"] = row["wall_ratio"] <= SPEED_BOUND
        rows.append(row)
        print(f"speed     {name:24s} {row['new']['seconds']:7.2f} s against {row['baseline']['seconds']:7.2f} s "
              f"(x{row['wall_ratio']:.3f} wall, x{row['cpu_ratio']:.3f} CPU; medians of {repeat})"
              f"{'' if row['met'] else '  missed: seconds'}", flush=True)
    return {"baseline": str(args.baseline_facetree), "bound": SPEED_BOUND, "rows": rows}


# The cluster file's node bytes against an earlier build's (--baseline-facetree, a version 1 writer):
# per shared mesh the nodes' compressed bytes per node with exact and compact boxes and their ratios
# to the baseline's (targets: at most FORMAT_EXACT_BOUND and FORMAT_COMPACT_BOUND; dragon_vrip at
# most FORMAT_DRAGON_BYTES), every file verified for b = 2, 4, 8 in core and (b = 2) out of core;
# the in-core write phase of dragon_vrip, alternating with the baseline (median; target at most
# FORMAT_WRITE_BOUND of it); and truncation by bytes: nodes kept for the same budgets.
FORMAT_EXACT_BOUND, FORMAT_COMPACT_BOUND = 0.65, 0.42
FORMAT_DRAGON_BYTES = {"exact": 48.0, "compact": 30.0}
FORMAT_WRITE_BOUND, FORMAT_TRUNCATE_BOUND = 0.5, 1.5


def node_bytes(args, binary, fch):
    return run_json([binary if binary else args.facetree, "info", fch, "--json"])["node_bytes_per_node"]


# Tiles (facetree tiles): on dragon_vrip and the subdivided dragons, the build and the tiling
# alternate (medians); targets: tiling without Draco at most TILES_TIME_BOUND of the build that wrote
# the file, the whole tileset at most TILES_SIZE_BOUND of its leaves' bytes with and without Draco,
# the peak RSS within the cap where one is given.
TILES_TIME_BOUND, TILES_SIZE_BOUND = 0.5, 1.6
TILES_CASES_FULL = [("dragon_vrip", 0, None, None, 3), ("14M-face dragon", 2, "256M", "64M", 1),
                    ("56M-face dragon", 3, "256M", "256M", 1)]
TILES_CASES_QUICK = [("dragon_vrip", 0, None, None, 3)]


def files_under(directory):
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


def tiles_as_tasks(args, fch, tiles, out, tiles_options):
    """The tiles of `fch` as the stage commands run them, one after another: each step's seconds,
    the largest peak RSS of a task, and whether the tileset is the bytes of `facetree tiles`."""
    run([args.facetree, "tiles", fch, "-o", tiles, *tiles_options])
    staged, work = out / "tiles_staged", out / "tiles_work"
    shutil.rmtree(work, ignore_errors=True)
    stdout, plan_wall, _, plan_rss = run_measured([args.facetree, "stage", "tiles-plan", fch, "--work", work, "-o",
                                                   staged, "--json", *tiles_options])
    tasks = json.loads(stdout)["tasks"]
    task_wall, peak = 0.0, plan_rss
    for task in range(tasks):
        _, wall, _, rss = run_measured([args.facetree, "stage", "tiles", "--work", work, "--task", str(task)])
        task_wall, peak = task_wall + wall, max(peak, rss)
    _, finish_wall, _, finish_rss = run_measured([args.facetree, "stage", "tiles-finish", "--work", work])
    same = files_under(tiles) == files_under(staged)
    shutil.rmtree(staged, ignore_errors=True)
    shutil.rmtree(work, ignore_errors=True)
    return {"tasks": tasks, "plan_seconds": plan_wall, "tasks_seconds": task_wall, "finish_seconds": finish_wall,
            "seconds": plan_wall + task_wall + finish_wall, "peak_rss_bytes": max(peak, finish_rss),
            "same_bytes": same}


def bench_tiles(args, out):
    rows = []
    for name, levels, build_cap, tiles_cap, repeat in TILES_CASES_QUICK if args.quick else TILES_CASES_FULL:
        mesh = mesh_path("dragon_vrip")
        if levels:
            mesh = out / f"tiles_dragon{levels}.ply"
            run([args.facetree, "gen", "subdivide", mesh_path("dragon_vrip"), "--levels", str(levels), "-o", mesh])
        fch, tiles = out / "tiles.fch", out / "tiles_out"
        build_options = ["--memory", build_cap] if build_cap else []
        tiles_options = ["--memory", tiles_cap] if tiles_cap else []
        samples = {"build": [], "tiles": [], "draco": []}
        reports = {}
        for _ in range(repeat):
            _, wall, cpu, rss = run_measured([args.facetree, "build", mesh, "-o", fch, *build_options])
            samples["build"].append({"seconds": wall, "cpu_seconds": cpu, "peak_rss_bytes": rss})
            for kind, extra in (("tiles", []), ("draco", ["--draco"])):
                stdout, wall, cpu, rss = run_measured([args.facetree, "tiles", fch, "-o", tiles, "--json",
                                                       *tiles_options, *extra])
                samples[kind].append({"seconds": wall, "cpu_seconds": cpu, "peak_rss_bytes": rss})
                reports[kind] = json.loads(stdout)
        if levels:
            mesh.unlink()
        staged = tiles_as_tasks(args, fch, tiles, out, tiles_options)
        row = {"case": name, "runs": repeat, "build_cap": build_cap, "tiles_cap": tiles_cap, "stages": staged}
        for kind, runs in samples.items():
            row[kind] = {k: median(r[k] for r in runs) for k in ("seconds", "cpu_seconds", "peak_rss_bytes")}
        for kind, report in reports.items():
            row[kind].update({k: report[k] for k in ("tiles", "leaf_tiles", "levels", "bytes", "leaf_bytes",
                                                     "tile_faces", "workers")})
            row[kind]["size_ratio"] = report["bytes"] / report["leaf_bytes"]
        row["time_ratio"] = row["tiles"]["seconds"] / row["build"]["seconds"]
        row["draco_time_ratio"] = row["draco"]["seconds"] / row["build"]["seconds"]
        cap = cap_bytes(tiles_cap) if tiles_cap else None
        row["checks"] = {
            "time_within_0.5x_build": row["time_ratio"] <= TILES_TIME_BOUND,
            "size_within_1.6x_leaves": row["tiles"]["size_ratio"] <= TILES_SIZE_BOUND,
            "draco_size_within_1.6x_leaves": row["draco"]["size_ratio"] <= TILES_SIZE_BOUND,
            "peak_within_cap": cap is None or max(row["tiles"]["peak_rss_bytes"], row["draco"]["peak_rss_bytes"]) <= cap,
            "stages_same_bytes": staged["same_bytes"],
            "stages_peak_within_cap": cap is None or staged["peak_rss_bytes"] <= cap,
        }
        rows.append(row)
        shutil.rmtree(tiles, ignore_errors=True)
        fch.unlink(missing_ok=True)
        print(f"tiles     {name:18s} build {row['build']['seconds']:7.2f} s, tiles {row['tiles']['seconds']:6.2f} s "
              f"(x{row['time_ratio']:.2f}), Draco {row['draco']['seconds']:6.2f} s; {row['tiles']['tiles']} tiles, "
              f"{row['tiles']['size_ratio']:.2f}x / {row['draco']['size_ratio']:.2f}x the leaves; peak "
              f"{row['tiles']['peak_rss_bytes'] / 2**20:.0f} MiB; as {staged['tasks']} tasks "
              f"{staged['seconds']:.2f} s, peak {staged['peak_rss_bytes'] / 2**20:.0f} MiB" + "".join(
                  f"  missed: {k}" for k, ok in row["checks"].items() if not ok), flush=True)
    return {"time_bound": TILES_TIME_BOUND, "size_bound": TILES_SIZE_BOUND, "rows": rows}


def bench_format(args, meshes, out):
    if not args.baseline_facetree:
        print("format    skipped: no --baseline-facetree", flush=True)
        return {"skipped": "no --baseline-facetree"}
    base, new = args.baseline_facetree, args.facetree
    fch = out / "format.fch"
    rows = []
    for mesh in meshes:
        row = {"mesh": mesh}
        run([base, "build", mesh_path(mesh), "-o", fch])
        row["baseline"] = node_bytes(args, new, fch)
        for boxes in ("exact", "compact"):
            for b in (2, 4, 8):
                run([new, "build", mesh_path(mesh), "-o", fch, "--boxes", boxes, "--branching", b])
                run([new, "verify", fch])
                if b == 2:
                    row[boxes] = node_bytes(args, new, fch)
            run([new, "build", mesh_path(mesh), "-o", fch, "--boxes", boxes, "--cell-faces", 20000])
            run([new, "verify", fch])
            row[f"{boxes}_ratio"] = row[boxes] / row["baseline"]
        row["met"] = row["exact_ratio"] <= FORMAT_EXACT_BOUND and row["compact_ratio"] <= FORMAT_COMPACT_BOUND
        rows.append(row)
        print(f"format    {mesh:24s} {row['baseline']:6.1f} B/node -> exact {row['exact']:5.1f} "
              f"(x{row['exact_ratio']:.3f}), compact {row['compact']:5.1f} (x{row['compact_ratio']:.3f})"
              f"{'' if row['met'] else '  missed'}", flush=True)
    dragon = next((r for r in rows if r["mesh"] == "dragon_vrip"), None)
    # The write phase, alternating builds.
    writes = {"baseline": [], "new": []}
    for _ in range(1 if args.quick else 5):
        for which, binary in (("baseline", base), ("new", new)):
            writes[which].append(run_json([binary, "build", mesh_path("dragon_vrip"), "-o", fch, "--json"])
                                 ["seconds"]["write"])
    write = {k: median(v) for k, v in writes.items()}
    write["ratio"] = write["new"] / write["baseline"]
    write["met"] = write["ratio"] <= FORMAT_WRITE_BOUND
    print(f"format    dragon_vrip write phase {write['new']:.3f} s against {write['baseline']:.3f} s "
          f"(x{write['ratio']:.3f}){'' if write['met'] else '  missed'}", flush=True)
    # Truncation by bytes: the geometry plus a share of the baseline file's nodes.
    run([base, "build", mesh_path("dragon_vrip"), "-o", out / "format_v1.fch"])
    run([new, "build", mesh_path("dragon_vrip"), "-o", fch])
    info = run_json([new, "info", out / "format_v1.fch", "--json"])
    geometry = info["bytes"] - info["sections"]["nodes"]["compressed_bytes"]
    truncation = []
    for share in (0.05, 0.25, 0.5):
        budget = int(geometry + share * (info["bytes"] - geometry))
        kept = {}
        for which, binary, source in (("baseline", base, out / "format_v1.fch"), ("new", new, fch)):
            kept[which] = run_json([binary, "truncate", source, "-o", out / "format_cut.fch", "--max-bytes", budget,
                                    "--json"])["nodes"]
        truncation.append({"max_bytes": budget, **kept, "ratio": kept["new"] / kept["baseline"],
                           "met": kept["new"] >= FORMAT_TRUNCATE_BOUND * kept["baseline"]})
        print(f"format    truncate --max-bytes {budget}: {kept['new']} nodes against {kept['baseline']} "
              f"(x{kept['new'] / kept['baseline']:.2f})", flush=True)
    for f in (fch, out / "format_v1.fch", out / "format_cut.fch"):
        f.unlink(missing_ok=True)
    return {"baseline": str(base), "rows": rows, "exact_bound": FORMAT_EXACT_BOUND,
            "compact_bound": FORMAT_COMPACT_BOUND,
            "dragon_vrip": dragon and {boxes: {"bytes_per_node": dragon[boxes],
                                               "met": dragon[boxes] <= FORMAT_DRAGON_BYTES[boxes]}
                                       for boxes in ("exact", "compact")},
            "write": write, "truncation": truncation}


def bench_python(args):
    build_dir = pathlib.Path(args.facetree).resolve().parent.parent
    library = build_dir / "tests" / "library_build"
    if not (build_dir / "python" / "facetree").is_dir() or not library.is_file():
        sys.exit(f"bench: python needs a build with -DFACETREE_PYTHON=ON ({build_dir})")
    mesh = mesh_path("dragon_vrip")
    env = dict(os.environ, PYTHONPATH=str(build_dir / "python"))
    repeat = max(args.repeat, 9)

    def runs(command):
        result = subprocess.run(command, capture_output=True, text=True, env=env, check=True)
        return [json.loads(line) for line in result.stdout.splitlines()]

    samples = {"library": [], "python": [], "python_converted": []}
    for _ in range(repeat):  # interleaved: one process of each per repetition
        samples["library"] += runs([str(library), str(mesh), "1"])
        samples["python"] += runs([sys.executable, "-c", PYTHON_BUILD, str(mesh), "1", "native"])
        samples["python_converted"] += runs([sys.executable, "-c", PYTHON_BUILD, str(mesh), "1", "wide"])
    summary = {}
    for name, values in samples.items():
        summary[name] = {"seconds": median([v["seconds"] for v in values]),
                         "cpu_seconds": median([v["cpu_seconds"] for v in values]),
                         "seconds_all": [v["seconds"] for v in values],
                         "rss_added_bytes": median([v["rss_peak"] - v["rss_base"] for v in values]),
                         "nodes": values[0]["nodes"]}
    summary["input_copied"] = samples["python"][0]["copied"]
    summary["converted_input_copied"] = samples["python_converted"][0]["copied"]
    # Each repetition ran the library and the binding back to back: the median of their ratios.
    time_ratio = median([p["seconds"] / c["seconds"] for p, c in zip(samples["python"], samples["library"])])
    cpu_ratio = median([p["cpu_seconds"] / c["cpu_seconds"] for p, c in zip(samples["python"], samples["library"])])
    added = summary["python"]["rss_added_bytes"] - summary["library"]["rss_added_bytes"]
    vertices, faces = 437645, 871414
    input_bytes = 12 * vertices + 12 * faces  # float32 positions and uint32 indices
    summary["ratios"] = {"python_over_library_seconds": time_ratio, "python_over_library_cpu_seconds": cpu_ratio,
                         "python_minus_library_rss_added_bytes": added,
                         "input_bytes": input_bytes}
    summary["checks"] = {
        "python within 5% of the library call (wall)": time_ratio <= 1.05,
        "python within 5% of the library call (CPU)": cpu_ratio <= 1.05,
        "no copy of the input (flags)": summary["input_copied"] == {"vertices": False, "faces": False},
        "no copy of the input (resident set: the build adds at most 1 MiB more than in C++)": added <= 2**20,
    }
    print(f"python: library {summary['library']['seconds']:.3f} s, python {summary['python']['seconds']:.3f} s "
          f"(x{time_ratio:.3f} wall, x{cpu_ratio:.3f} CPU, medians of paired runs), converted {summary['python_converted']['seconds']:.3f} s; resident set added: "
          f"library {summary['library']['rss_added_bytes'] / 2**20:.1f} MiB, python "
          f"{summary['python']['rss_added_bytes'] / 2**20:.1f} MiB, converted "
          f"{summary['python_converted']['rss_added_bytes'] / 2**20:.1f} MiB (input {input_bytes / 2**20:.1f} MiB)")
    for check, ok in summary["checks"].items():
        print(f"  {'ok  ' if ok else 'MISS'} {check}")
    return summary


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--facetree", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--quick", action="store_true",
                        help="four meshes, small generated sizes, the Garland metric once per mesh")
    parser.add_argument("--repeat", type=int, default=3, help="runs per case (default 3)")
    parser.add_argument("--only", choices=SECTIONS + ["files"], action="append",
                        help="run only these sections (repeatable; files is the old name of branching)")
    parser.add_argument("--no-pictures", dest="pictures", action="store_false",
                        help="skip the cluster pictures of the balance section")
    parser.add_argument("--no-callgrind", dest="callgrind", action="store_false",
                        help="skip the callgrind instruction counts of the octree section")
    parser.add_argument("--baseline-facetree", metavar="BIN",
                        help="an earlier build's facetree for the speed section, run alternately with --facetree")
    parser.add_argument("--keep-from", type=pathlib.Path, metavar="BENCH.json",
                        help="copy the sections not run now from an earlier report (with its date and load), "
                             "so that `--only SECTION --keep-from OLD.json` updates one section of the docs")
    args = parser.parse_args()
    args.callgrind = args.callgrind and shutil.which("valgrind") is not None
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    all_meshes = sorted((p.name[:-len(".ply.zst")] for p in SHARED.glob("*.ply.zst")),
                        key=lambda m: mesh_path(m).stat().st_size)
    if not all_meshes:
        sys.exit(f"bench: no meshes in {SHARED}")
    meshes = [m for m in all_meshes if m in QUICK_MESHES] if args.quick else all_meshes
    sections = [("branching" if s == "files" else s) for s in (args.only or SECTIONS)]
    started = time.time()
    report = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": platform.node(), "cpus": os.cpu_count(),
        "cpu_model": cpu_model(), "memory_bytes": memory_bytes(), "load_average_start": os.getloadavg(),
        "quick": args.quick, "repeat": args.repeat, "facetree": str(args.facetree),
    }
    runs = MeshRuns(args, out)
    report["section_seconds"] = section_seconds = {}
    report["section_load_average_end"] = section_load = {}
    lap = time.time()

    def section_done(name):
        # Wall time per section, to find the one that makes a run long; the shared per-mesh
        # builds are counted in the first section that asks for a mesh.
        nonlocal lap
        section_seconds[name], lap = time.time() - lap, time.time()
        section_load[name] = os.getloadavg()[0]

    # Each section's runner, in the order the sections run.
    runners = {
        "read": lambda: bench_read(args, ["dragon_vrip", "fg_hawaii"] if args.quick else all_meshes),
        "build": lambda: bench_build(args, meshes, runs),
        "profile": lambda: bench_profile(args, runs),
        "balance": lambda: bench_balance(args, meshes, runs, out),
        "scaling": lambda: bench_scaling(args, meshes, runs, out),
        "octree": lambda: bench_octree(args, meshes, runs, out),
        "branching": lambda: bench_branching(
            args, ["bunny_zipper", "turbine_blade_200k"] if args.quick else QUICK_MESHES, out),
        "flat": lambda: bench_flat(args, out),
        "rounds": lambda: bench_rounds(args, meshes, out),
        "outofcore": lambda: bench_outofcore(args, out),
        "python": lambda: bench_python(args),
        "queries": lambda: bench_queries(args, meshes, out),
        "speed": lambda: bench_speed(args, out),
        "format": lambda: bench_format(args, meshes, out),
        "tiles": lambda: bench_tiles(args, out),
    }
    for name, run in runners.items():
        if name in sections:
            report[name] = run()
            section_done(name)
            # What has run so far, so that a section that fails leaves the others' figures behind
            # (`--keep-from` takes them).
            (out / "bench.partial.json").write_text(json.dumps(report, indent=1))
    report["load_average_end"] = os.getloadavg()
    report["wall_seconds"] = time.time() - started
    if args.keep_from:
        earlier = json.loads(args.keep_from.read_text())
        kept = [s for s in SECTIONS if s not in sections and s in earlier]
        for section in kept:
            report[section] = earlier[section]
        report["kept_from"] = {"sections": kept, "quick": earlier.get("quick"), "repeat": earlier.get("repeat"),
                               **{k: earlier.get(k) for k in ("date", "load_average_start", "load_average_end",
                                                              "wall_seconds")}}
    (out / "bench.json").write_text(json.dumps(report, indent=1))
    print(f"bench: wrote {out / 'bench.json'} in {report['wall_seconds'] / 60:.1f} min")


def cpu_model():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def memory_bytes():
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError):
        return None


if __name__ == "__main__":
    main()
