#!/usr/bin/env python3
"""facetree benchmarks: each case run several times, medians reported, comparisons as ratios
against a baseline measured in the same invocation (the machine is shared and noisy).

Sections:
  read   mesh reading throughput (facetree stats) against `zstd -dc` of the same file
  build  file to hierarchy with boxes per shared mesh: time per phase, peak RSS, height/balanced,
         dual-edge degree; ratio to the read time of the same mesh
  files  cluster file size per mesh for branching 2, 4 and 8, verified
  flat   flat regular grids (Willmott 2000, Figs 69-71): time and maximum dual-edge degree for
         the default metric against the constant-cost and Garland metrics, and the log-log slope

Writes OUT/bench.json and prints a table per section.
"""
import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time

SHARED = pathlib.Path(__file__).resolve().parent.parent.parent / "shared" / "data"
QUICK_MESHES = ["bunny_zipper", "dragon_vrip", "openfoam_buildings", "turbine_blade_200k"]


def run_json(command):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} failed: {result.stderr.strip()}")
    return json.loads(result.stdout)


def timed(command):
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def repeat_runs(repeat, function):
    return [function() for _ in range(repeat)]


def bench_read(args, meshes):
    rows = []
    for mesh in meshes:
        path = SHARED / f"{mesh}.ply.zst"
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
        print(f"read  {mesh:24s} {seconds:7.3f} s  {rows[-1]['mb_per_second']:7.1f} MB/s  "
              f"{rows[-1]['faces_per_second'] / 1e6:6.2f} M faces/s  peak {rows[-1]['peak_rss_bytes'] / 2**20:6.1f} MiB  "
              f"x{rows[-1]['ratio_to_zstd']:.2f} of zstd -dc", flush=True)
    return rows


def bench_build(args, meshes, extra=()):
    rows = []
    for mesh in meshes:
        path = SHARED / f"{mesh}.ply.zst"
        builds = repeat_runs(args.repeat, lambda: run_json([args.facetree, "build", "--json", path, *extra]))
        reads = repeat_runs(args.repeat, lambda: run_json([args.facetree, "stats", "--json", path]))
        first = builds[0]
        phases = {k: statistics.median(b["seconds"][k] for b in builds) for k in first["seconds"]}
        read_seconds = statistics.median(r["read_seconds"] for r in reads)
        row = {
            "mesh": mesh, "options": list(extra), "triangles": first["triangles"], "seconds": phases,
            "peak_rss_bytes": max(b["peak_rss_bytes"] for b in builds),
            "height": first["height"], "balanced_height": first["balanced_height"],
            "height_ratio": first["height_ratio"], "average_degree": first["average_degree"],
            "max_degree": first["max_degree"], "components": first["components"],
            "read_seconds": read_seconds, "ratio_to_read": phases["total"] / read_seconds,
        }
        rows.append(row)
        print(f"build {mesh:24s} {phases['total']:7.3f} s (merge {phases['merge']:.3f}, boxes {phases['boxes']:.3f})  "
              f"peak {row['peak_rss_bytes'] / 2**20:6.1f} MiB  height {row['height']}/{row['balanced_height']} "
              f"= {row['height_ratio']:.2f}  degree {row['average_degree']:.2f}/{row['max_degree']}  "
              f"x{row['ratio_to_read']:.1f} of reading", flush=True)
    return rows


def bench_files(args, meshes, tmp):
    rows = []
    for mesh in meshes:
        path = SHARED / f"{mesh}.ply.zst"
        for branching in (2, 4, 8):
            out = tmp / f"{mesh}.b{branching}.fch"
            run_json([args.facetree, "build", "--json", path, "-o", out, "--branching", str(branching)])
            verify = subprocess.run([args.facetree, "verify", out], capture_output=True, text=True)
            info = run_json([args.facetree, "info", "--json", out])
            size = out.stat().st_size
            out.unlink()
            rows.append({"mesh": mesh, "branching": branching, "bytes": size, "info": info,
                         "verified": verify.returncode == 0})
            print(f"files {mesh:24s} b={branching}  {size / 1e6:8.2f} MB  verify "
                  f"{'ok' if verify.returncode == 0 else 'FAILED: ' + verify.stdout.strip()}", flush=True)
    return rows


def loglog_slope(points):
    """Least-squares slope of log(y) against log(x)."""
    import math
    xs = [math.log(x) for x, _ in points]
    ys = [math.log(max(y, 1e-9)) for _, y in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    var = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / var if var > 0 else float("nan")


def bench_flat(args, tmp):
    sizes = [10_000, 40_000, 160_000] if args.quick else [10_000, 40_000, 160_000, 640_000, 1_000_000, 4_000_000]
    # The constant metric is O(n^1.5 log n) (Fig. 69): keep it to the sizes that finish quickly.
    constant_limit = 160_000 if args.quick else 640_000
    rows = []
    for metric in ("willmott", "constant", "garland"):
        points = []
        for size in sizes:
            if metric == "constant" and size > constant_limit:
                continue
            mesh = tmp / f"grid_{size}.ply"
            if not mesh.exists():
                subprocess.run([args.facetree, "gen", "grid", "-n", str(size), "-o", mesh], check=True,
                               stderr=subprocess.DEVNULL)
            runs = repeat_runs(args.repeat, lambda: run_json(
                [args.facetree, "build", "--json", "--no-boxes", "--metric", metric, mesh]))
            seconds = statistics.median(r["seconds"]["total"] for r in runs)
            row = {"metric": metric, "triangles": runs[0]["triangles"], "seconds": seconds,
                   "max_degree": runs[0]["max_degree"], "average_degree": runs[0]["average_degree"],
                   "height": runs[0]["height"], "balanced_height": runs[0]["balanced_height"]}
            rows.append(row)
            points.append((row["triangles"], seconds))
            print(f"flat  {metric:9s} {row['triangles']:9d} tris  {seconds:8.3f} s  max degree {row['max_degree']:6d}  "
                  f"height {row['height']}/{row['balanced_height']}", flush=True)
        print(f"flat  {metric:9s} log-log slope of time {loglog_slope(points):.2f}", flush=True)
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--facetree", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--quick", action="store_true", help="a few meshes, 3 runs each")
    parser.add_argument("--repeat", type=int, default=0, help="runs per case (default 3 quick, 5 full)")
    parser.add_argument("--only", choices=["read", "build", "files", "flat"], action="append")
    args = parser.parse_args()
    args.repeat = args.repeat or (3 if args.quick else 5)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    all_meshes = sorted(p.name[:-len(".ply.zst")] for p in SHARED.glob("*.ply.zst"))
    if not all_meshes:
        sys.exit(f"bench: no meshes in {SHARED}")
    meshes = [m for m in QUICK_MESHES if m in all_meshes] if args.quick else all_meshes
    sections = args.only or ["read", "build", "files", "flat"]
    report = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": platform.node(), "cpus": os.cpu_count(),
        "load_average": os.getloadavg(), "quick": args.quick, "repeat": args.repeat,
    }
    if "read" in sections:
        report["read"] = bench_read(args, ["dragon_vrip", "fg_hawaii"] if args.quick else all_meshes)
    if "build" in sections:
        report["build"] = bench_build(args, meshes)
    if "files" in sections:
        report["files"] = bench_files(args, meshes, out)
    if "flat" in sections:
        report["flat"] = bench_flat(args, out)
        for mesh in out.glob("grid_*.ply"):
            mesh.unlink()
    (out / "bench.json").write_text(json.dumps(report, indent=1))
    print(f"bench: wrote {out / 'bench.json'}")


if __name__ == "__main__":
    main()
