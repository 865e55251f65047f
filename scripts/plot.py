#!/usr/bin/env python3
"""Turns scripts/bench's JSON into PNG figures and docs/benchmarks.md (tables, figures, the
machine and date they came from). Sections missing from the JSON are left out."""
import argparse
import json
import math
import os
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.ticker  # noqa: E402
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

DPI = 90
METRIC_LABEL = {"willmott": "default (Willmott eq. 84)", "garland": "Garland", "constant": "constant cost"}
METRIC_COLOR = {"willmott": "tab:blue", "garland": "tab:orange", "constant": "tab:gray"}


def save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    print(f"plot: {path} ({path.stat().st_size // 1024} KB)")


def describe(ax, title, xlabel=None, ylabel=None, legend_size=7):
    """An axes' labels, legend and title, the same way in every figure."""
    if xlabel is not None:
        ax.set_xlabel(xlabel)
    if ylabel is not None:
        ax.set_ylabel(ylabel)
    ax.legend(fontsize=legend_size)
    ax.set_title(title, fontsize=10)


def short(mesh):
    return mesh.replace("_", " ")


def fit_line(ax, points, color, label_prefix, extend_to=None, extend_label=None):
    """Draws the least-squares log-log line through points (dotted on to x = extend_to when given);
    returns its slope."""
    points = [(x, y) for x, y in points if x > 0 and y > 0]
    if len(points) < 2:
        return float("nan")
    xs = [math.log(x) for x, _ in points]
    ys = [math.log(y) for _, y in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    lo, hi = min(xs), max(xs)
    ax.plot([math.exp(lo), math.exp(hi)], [math.exp(my + slope * (lo - mx)), math.exp(my + slope * (hi - mx))],
            color=color, linestyle="--", linewidth=1, label=f"{label_prefix} slope {slope:.2f}")
    if extend_to and math.log(extend_to) > hi:
        far = math.log(extend_to)
        ax.plot([math.exp(hi), extend_to], [math.exp(my + slope * (hi - mx)), math.exp(my + slope * (far - mx))],
                color=color, linestyle=":", linewidth=1, label=extend_label)
    return slope


# --- figures ----------------------------------------------------------------------------------

def plot_profile(rows, path):
    # Shares rather than seconds: the two metrics ran at different moments of a shared machine.
    labels = rows[0]["phase_labels"]
    fig, ax = plt.subplots(figsize=(7.5, 3.0))
    colors = ["tab:red", "tab:orange", "tab:blue", "tab:green", "tab:purple", "tab:gray"]
    for y, row in enumerate(rows):
        left = 0.0
        for (key, label), color in zip(labels, colors):
            width = 100 * row["phases"][key] / row["total"]
            ax.barh(y, width, left=left, color=color, label=label if y == 0 else None)
            left += width
    ax.set_yticks(range(len(rows)), [f"{METRIC_LABEL[r['metric']]}\n{r['total']:.1f} s" for r in rows], fontsize=8)
    ax.set_xlim(0, 100)
    ax.set_xlabel(f"% of the build without reading (wall, median), {rows[0]['mesh']}, {rows[0]['triangles']:,} triangles",
                  fontsize=8)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.28), ncol=3, frameon=False)
    ax.set_title("Profile per phase (cf. Willmott Tables 5 and 8)", fontsize=10)
    save(fig, path)


def plot_balance(balance, path):
    rows = sorted(balance["meshes"], key=lambda r: r["triangles"])
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8))
    x = range(len(rows))
    ax.bar([i - 0.2 for i in x], [r["willmott"]["height"] / r["balanced_height"] for r in rows], 0.4,
           color=METRIC_COLOR["willmott"], label=METRIC_LABEL["willmott"])
    nan = float("nan")
    ax.bar([i + 0.2 for i in x], [r["garland"]["height"] / r["balanced_height"] if r["garland"] else nan for r in rows], 0.4,
           color=METRIC_COLOR["garland"], label=METRIC_LABEL["garland"])
    for i, r in enumerate(rows):
        if not r["garland"]:
            ax.text(i + 0.2, 1.15, "Garland skipped", fontsize=6, rotation=90, ha="center", va="bottom")
    ax.axhline(1, color="black", linewidth=0.8)
    ax.set_yscale("log")
    ax.set_ylabel("tree height / balanced height")
    ax.set_xticks(list(x), [short(r["mesh"]) for r in rows], rotation=60, ha="right", fontsize=7)
    ax.legend(fontsize=8)
    ax.set_title("Balance (cf. Table 6, Fig. 73)", fontsize=10)
    bx.bar([i - 0.2 for i in x], [r["willmott"]["boxes_seconds"] for r in rows], 0.4, color=METRIC_COLOR["willmott"],
           label=METRIC_LABEL["willmott"])
    bx.bar([i + 0.2 for i in x], [r["garland"]["boxes_seconds"] if r["garland"] else nan for r in rows], 0.4,
           color=METRIC_COLOR["garland"],
           label=METRIC_LABEL["garland"])
    bx.set_yscale("log")
    bx.set_ylabel("box + side-area time, s (wall)")
    bx.set_xticks(list(x), [short(r["mesh"]) for r in rows], rotation=60, ha="right", fontsize=7)
    bx.set_title("Box computation time", fontsize=10)
    save(fig, path)


def plot_k(k_rows, path):
    fig, ax = plt.subplots(figsize=(6, 3.6))
    meshes = sorted({r["mesh"] for r in k_rows})
    for i, mesh in enumerate(meshes):
        color = plt.cm.tab10(i)
        for slack, style in ((1.5, "-"), (0.0, ":")):
            rows = sorted((r for r in k_rows if r["mesh"] == mesh and r.get("balance_slack", 1.5) == slack),
                          key=lambda r: r["k"])
            if not rows:
                continue
            # k = 0 cannot sit on a log axis: drawn at 1e-6, labelled as 0.
            ax.plot([r["k"] or 1e-6 for r in rows], [r["height"] / r["balanced_height"] for r in rows], style,
                    marker="o", color=color,
                    label=f"{short(mesh)}, " + ("balance guard (default)" if slack else "no guard (pure eq. 84)"))
    ax.set_xscale("log")
    ratios = [r["height"] / r["balanced_height"] for r in k_rows]
    if max(ratios) > 5 * min(ratios):  # a full run's no-guard heights span decades
        ax.set_yscale("log")
        # Plain numbers, the minor ticks at 2 and 5 labelled too (a decade has one power of ten).
        ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(
            lambda v, _: f"{v:g}" if f"{v:.1e}"[0] in "125" else ""))
    ax.set_xticks([1e-6, 1e-5, 1e-4, 1e-3], ["0", "1e-5", "1e-4\n(default)", "1e-3"])
    describe(ax, "Height against k (cf. Fig. 73)", "k (balance weight, eq. 80)", "height / balanced height")
    save(fig, path)


def plot_pictures(pictures, path):
    meshes = sorted({p["mesh"] for p in pictures})
    metrics = ["willmott", "garland"]
    fig, axes = plt.subplots(len(meshes), 2, figsize=(7, 3.1 * len(meshes)), squeeze=False)
    for i, mesh in enumerate(meshes):
        for j, metric in enumerate(metrics):
            ax = axes[i][j]
            ax.axis("off")
            match = [p for p in pictures if p["mesh"] == mesh and p["metric"] == metric]
            if match and pathlib.Path(match[0]["png"]).exists():
                ax.imshow(mpimg.imread(match[0]["png"]))
                ax.set_title(f"{short(mesh)}, {METRIC_LABEL[metric]}, cut {match[0]['cut']}", fontsize=8)
    fig.suptitle("Clusters of one cut (cf. Fig. 73)", fontsize=10)
    save(fig, path)


def log_axes(ax, xlabel, ylabel):
    """Log-log axes with plain numbers on the ticks (a decade or less has too few powers of ten)."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: count_label(v)))
    ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(
        lambda v, _: f"{v:g}" if f"{v:.1e}"[0] in "25" else ""))


def count_label(v):
    for unit, name in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if v >= unit:
            return f"{v / unit:g}{name}"
    return f"{v:g}"


def plot_scaling(scaling, path):
    points = scaling["points"]
    in_core = [p for p in points if not p.get("memory")]
    capped = [p for p in points if p.get("memory")]
    fig, ((ax, bx, cx), (lax, lbx, lcx)) = plt.subplots(2, 3, figsize=(13, 5.4),
                                                        gridspec_kw={"height_ratios": [4, 1.1]})
    for legend_ax in (lax, lbx, lcx):
        legend_ax.axis("off")
    for source, marker in (("shared", "o"), ("generated", "s")):
        sel = [p for p in in_core if p["source"] == source]
        ax.scatter([p["faces"] for p in sel], [p["cluster_seconds"] for p in sel], marker=marker,
                   color="tab:blue", label=f"{source} (wall)")
        ax.scatter([p["faces"] for p in sel], [p["process_cpu_seconds"] for p in sel], marker=marker,
                   facecolors="none", edgecolors="tab:red", label=f"{source} (CPU)")
        bx.scatter([p["faces"] for p in sel], [p["peak_rss_bytes"] / 2**20 for p in sel], marker=marker,
                   color="tab:green", label=source)
    for p in capped:  # out of core under a cap: a star, labelled, left out of the fitted lines
        label = f"{count_label(p['faces'])} out of core at {p['memory']}, 1 run"
        ax.scatter([p["faces"]], [p["cluster_seconds"]], marker="*", s=160, color="tab:blue",
                   label=f"{label} (wall)")
        ax.scatter([p["faces"]], [p["process_cpu_seconds"]], marker="*", s=160, facecolors="none",
                   edgecolors="tab:red", label=f"{label} (CPU)")
        bx.scatter([p["faces"]], [p["peak_rss_bytes"] / 2**20], marker="*", s=160, color="tab:purple", label=label)
        bx.axhline(cap_mib(p["memory"]), color="tab:purple", linestyle=":", linewidth=1,
                   label=f"cap {p['memory']}")
    fit = [p for p in in_core if p["faces"] >= 10_000]
    # The in-core fits run on dotted to the out-of-core point: where an in-core build would be.
    far = max((p["faces"] for p in capped), default=None)
    fit_line(ax, [(p["faces"], p["cluster_seconds"]) for p in fit], "tab:blue", "wall, in core:", far,
             "fits extrapolated")
    fit_line(ax, [(p["faces"], p["process_cpu_seconds"]) for p in fit], "tab:red", "CPU, in core:", far)
    fit_line(bx, [(p["faces"], p["peak_rss_bytes"] / 2**20) for p in fit], "tab:green", "in core, >= 10k faces:")
    large = [(p["faces"], p["peak_rss_bytes"] / 2**20) for p in fit if p["faces"] >= LARGE_FACES]
    if len(large) >= 2:
        fit_line(bx, large, "tab:olive", f"in core, >= {count_label(LARGE_FACES)} faces:")
    log_axes(ax, "faces", "seconds (clustering, without reading)")
    log_axes(bx, "faces", "peak RSS, MiB")
    # Legends in a row of their own below the panels: inside, they covered points.
    for a, legend_ax in ((ax, lax), (bx, lbx)):
        legend = legend_ax.legend(*a.get_legend_handles_labels(), fontsize=7, loc="upper center", ncol=2,
                                  frameon=False)
        legend.set_in_layout(False)
    ax.set_title("Time against faces (cf. Fig. 77)", fontsize=10)
    bx.set_title("Memory against faces (cf. Fig. 77)", fontsize=10)
    degree = [p for p in points if p.get("average_degree") is not None]
    cx.scatter([p["faces"] for p in degree], [p["average_degree"] for p in degree], color="tab:blue",
               label="average")
    cx.scatter([p["faces"] for p in degree], [p["max_degree"] for p in degree], color="tab:orange", label="maximum")
    log_axes(cx, "faces", "dual-edge degree")
    cx.legend(fontsize=7)
    cx.set_title("Degree per mesh, in core (cf. Fig. 78)", fontsize=10)
    save(fig, path)


# Below 100k faces peak RSS is mostly the process's fixed ~17.5 MiB, which flattens the RSS fit from
# 10k faces: its slope is given over the meshes of 100k faces and more as well.
LARGE_FACES = 100_000


def loglog_slope(points):
    points = [(math.log(x), math.log(y)) for x, y in points if x > 0 and y > 0]
    if len(points) < 2:
        return float("nan")
    mx, my = sum(x for x, _ in points) / len(points), sum(y for _, y in points) / len(points)
    return sum((x - mx) * (y - my) for x, y in points) / sum((x - mx) ** 2 for x, _ in points)


def large_rss_slope(s):
    return loglog_slope([(p["faces"], p["peak_rss_bytes"]) for p in s["points"]
                         if p["faces"] >= LARGE_FACES and not p.get("memory")])


def cap_mib(cap):
    return int(cap[:-1]) * {"M": 1, "G": 1024}[cap[-1]]


def plot_octree(octree, path):
    rows = sorted(octree["rows"], key=lambda r: r["triangles"])
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.6))
    faces = [r["triangles"] for r in rows]
    ax.loglog(faces, [r["cluster_seconds"] for r in rows], "o-", label="face clustering (hierarchy + boxes)")
    ax.loglog(faces, [r["octree_seconds"] for r in rows], "s-", label="tightest-fit octree")
    describe(ax, "Face clustering against octree (cf. Fig. 80)", "faces", "seconds (wall, median)", legend_size=8)
    # One point per mesh (not a series: no lines); the medians are over the meshes of 50k faces and
    # more, as in the text (below that the octree takes a millisecond or less: timer noise).
    bx.semilogx(faces, [r["ratio"] for r in rows], "o", color="tab:blue", label="wall-time ratio")
    bx.semilogx(faces, [r["ratio_cpu"] for r in rows], "s", color="tab:orange", markerfacecolor="none",
                label="CPU-time ratio")
    if octree.get("median_ratio"):
        big = [f for f in faces if f >= 50_000]
        for key, name, color in (("median_ratio", "wall", "tab:blue"), ("median_ratio_cpu", "CPU", "tab:orange")):
            bx.plot([min(big), max(big)], [octree[key]] * 2, color=color, linewidth=1,
                    label=f"{name} median over >= 50k faces: {octree[key]:.1f}")
        bx.axvline(50_000, color="gray", linestyle=":", linewidth=0.8)
    bx.axhline(2.5, color="black", linestyle="--", linewidth=0.8, label="seed: about 2.5")
    bx.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: count_label(v)))
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: count_label(v)))
    bx.set_ylim(bottom=0)
    describe(bx, "Ratio per mesh", "faces", "clustering time / octree time")
    save(fig, path)


def plot_branching(branching, path):
    sizes = branching["sizes"]
    meshes = sorted({r["mesh"] for r in sizes})
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.6))
    width = 0.8 / len(meshes)
    for i, mesh in enumerate(meshes):
        rows = sorted((r for r in sizes if r["mesh"] == mesh), key=lambda r: r["branching"])
        base = rows[0]["bytes"]
        ax.bar([j + (i - (len(meshes) - 1) / 2) * width for j in range(len(rows))], [r["bytes"] / base for r in rows],
               width, label=short(mesh))
    ax.set_xticks(range(3), ["b = 2", "b = 4", "b = 8"])
    ax.set_ylim(0, 1.1)
    describe(ax, "Cluster file size against branching", ylabel="file size / size at b = 2")
    for mesh in meshes:
        rows = sorted((p for p in branching["prefixes"] if p["mesh"] == mesh), key=lambda p: p["nodes"])
        bx.loglog([p["nodes"] for p in rows], [p["bytes"] / 1e6 for p in rows], "o-", label=short(mesh))
    describe(bx, "Truncated prefixes (b = 2)", "nodes kept (truncate --nodes)", "file size, MB")
    save(fig, path)


def plot_flat(flat, path):
    rows = flat["rows"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.6))
    for metric in ("willmott", "constant", "garland"):
        sel = sorted((r for r in rows if r["metric"] == metric), key=lambda r: r["triangles"])
        if not sel:
            continue
        color = METRIC_COLOR[metric]
        ax.loglog([r["triangles"] for r in sel], [r["seconds"] for r in sel], "o", color=color,
                  label=METRIC_LABEL[metric])
        fit_line(ax, [(r["triangles"], r["seconds"]) for r in sel], color, "")
        bx.loglog([r["triangles"] for r in sel], [r["max_degree"] for r in sel], "o-", color=color,
                  label=METRIC_LABEL[metric])
    describe(ax, "Flat grids: time (cf. Fig. 69)", "triangles", "seconds (wall, median, no boxes)")
    describe(bx, "Flat grids: maximum degree (cf. Fig. 71)", "triangles", "maximum dual-edge degree")
    save(fig, path)


def cap_label(cap):
    return cap or "in core"


def plot_outofcore(o, path):
    rows = o["rows"]
    caps = [cap_label(r["memory"]) for r in rows if r["input"] == "coherent"]
    fig, (ax, bx, cx) = plt.subplots(1, 3, figsize=(13, 3.8))
    x = range(len(caps))
    for i, (order, color) in enumerate((("coherent", "tab:blue"), ("shuffled", "tab:orange"))):
        sel = [r for r in rows if r["input"] == order]
        offset = [j + (i - 0.5) * 0.38 for j in x]
        ax.bar(offset, [r["seconds"] for r in sel], 0.38, color=color, label=f"{order} (wall)")
        ax.scatter(offset, [r["process_cpu_seconds"] for r in sel], color="black", marker="_", s=120,
                   label="process CPU" if i == 0 else None, zorder=3)
        bx.bar(offset, [r["process_peak_rss_bytes"] / 2**20 for r in sel], 0.38, color=color, label=order)
        for j, r in zip(offset, sel):
            if r["out_of_core"]:
                ax.annotate(f"{r['cells']} cells", (j, r["seconds"]), ha="center", va="bottom", fontsize=6)
    for j, r in enumerate(r for r in rows if r["input"] == "coherent"):
        if r["memory"]:
            bx.hlines(cap_bytes_mib(r["memory"]), j - 0.45, j + 0.45, color="black", linestyle="--", linewidth=1,
                      label="cap" if j == 0 else None)
    for a, label in ((ax, "seconds"), (bx, "peak RSS (wait4), MiB")):
        a.set_xticks(list(x), [f"--memory {c}" if c != "in core" else c for c in caps], fontsize=7)
        a.set_ylabel(label)
        a.legend(fontsize=7)
    bx.set_yscale("log")
    ax.set_title(f"{rows[0]['mesh']} ({rows[0]['triangles']:,} faces): build time", fontsize=10)
    bx.set_title("Peak resident memory against the cap", fontsize=10)
    q = [r for r in o["quality"] if r["cell_faces"] is not None]
    cuts = [str(n) for n in o["fit_cuts"]]
    series = [(f"sum eFit, {int(n):,} clusters", lambda r, n=n: r["ratio"]["sum_fit"][n]) for n in cuts]
    series.append(("height", lambda r: r["ratio"]["height"]))
    width = 0.8 / len(series)
    for k, (label, value) in enumerate(series):
        cx.bar([j + (k - (len(series) - 1) / 2) * width for j in range(len(q))], [value(r) for r in q], width,
               label=label)
    cx.axhline(1.0, color="black", linewidth=0.8)
    cx.axhline(1.1, color="black", linestyle="--", linewidth=0.8, label="aim: within 10%")
    cx.set_xticks(range(len(q)), [f"{short(r['mesh'])}\ncells of {r['cell_faces'] // 1000}k" for r in q], fontsize=7)
    cx.set_ylabel("out of core / in core")
    # Room above the bars for the legend, which covered them at the bottom.
    cx.set_ylim(0, 1.6 if max(b.get_height() for b in cx.patches) < 1.3 else None)
    cx.legend(fontsize=7, loc="upper center", ncol=2)
    cx.set_title("Quality of forced out-of-core builds", fontsize=10)
    save(fig, path)


def cap_bytes_mib(cap):
    return int(cap[:-1]) * {"M": 1, "G": 1024}[cap[-1]]


# --- markdown ---------------------------------------------------------------------------------

def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---:" if i else "---" for i in range(len(header))) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def mib(b):
    return f"{b / 2**20:.1f}"


def without_boxes(report, octree_row):
    """(clustering - boxes) / octree from the medians of the same default-metric runs."""
    for row in report.get("balance", {}).get("meshes", []):
        if row["mesh"] == octree_row["mesh"]:
            rest = row["willmott"]["cluster_seconds"] - row["willmott"]["boxes_seconds"]
            return f"{rest / octree_row['octree_seconds']:.1f}"
    return ""



QUERY_KINDS = [("camera", "rays_per_second", "camera rays, closest hit"),
               ("random", "rays_per_second", "random rays, closest hit"),
               ("boxes", "queries_per_second", "box overlap"),
               ("nearest", "queries_per_second", "nearest point")]


def query_relative(q, kind, field, b, prefix):
    """The median over the meshes of a figure at branching b against b = 2's, same mesh and prefix."""
    values = []
    for r in q["experiment"]:
        if r["branching"] != b or r["prefix"] != prefix:
            continue
        base = next(x for x in q["experiment"] if x["mesh"] == r["mesh"] and x["branching"] == 2
                    and x["prefix"] == prefix)
        if base[kind][field]:
            values.append(r[kind][field] / base[kind][field])
    values.sort()
    return values[len(values) // 2] if values else float("nan")


def query_work(record):
    return record.get("boxes_per_ray", record.get("boxes_per_query", 0)) + \
        record.get("triangles_per_ray", record.get("triangles_per_query", 0))


def plot_queries(q, path):
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.6))
    bs = [2, 4, 8]
    bound = [(b / math.log2(b)) / 2 for b in bs]
    for ax, (kind, rate, title) in zip(axes, QUERY_KINDS):
        for prefix, color in zip((0.01, 0.1, 1.0), ("tab:orange", "tab:green", "tab:blue")):
            time = [1 / query_relative(q, kind, rate, b, prefix) for b in bs]
            ax.plot(bs, time, "o-", color=color, label=f"time, {prefix:g} of the nodes")
            boxes = [query_relative(q, kind, "boxes_per_ray" if "rays" in rate else "boxes_per_query", b, prefix)
                     for b in bs]
            ax.plot(bs, boxes, "x--", color=color, alpha=0.6, label=f"boxes tested, {prefix:g}")
        ax.plot(bs, bound, "k:", label="bound (b / log2 b) / 2")
        ax.set_xticks(bs)
        describe(ax, title, "branching b", "against b = 2 (median over meshes)", legend_size=6)
    save(fig, path)


def queries_markdown(q, rel):
    out = ["## Queries and the branching factor (Willmott 2000, sec. 5.5.1)", "",
           (f"Measured {q['date']}. " if q.get("date") else "") + f"Every shared mesh built with b = 2, 4 and 8 and read in memory, whole and truncated to 10% and 1% "
           f"of its nodes (a cut-off node's faces are tested). {q['rays']:,} camera rays (a pinhole camera "
           f"outside the bounding sphere) and {q['rays']:,} random rays (origins in the box grown by a tenth, "
           f"directions uniform) for closest hits; {q['queries']:,} boxes about surface points (a hundredth "
           "of the diagonal, one in ten oriented) and as many nearest-point queries from random points; one "
           "thread (`tests/query/query_bench`). Figures are medians over the meshes of the ratio to b = 2 on "
           "the same mesh and prefix: query time, and oriented boxes tested. Sec. 5.5.1 bounds the query "
           "time of a b-ary tree against the binary one by b / log b: b children tested at each of "
           "log_b n levels against 2 at each of log_2 n, (b / log2 b) / 2, 1.00 for b = 4 and 1.33 for "
           "b = 8.", ""]
    rows = []
    for kind, rate, title in QUERY_KINDS:
        for prefix in (1.0, 0.1, 0.01):
            row = [title, f"{prefix:g}"]
            for b in (4, 8):
                row.append(f"{1 / query_relative(q, kind, rate, b, prefix):.2f}")
                field = "boxes_per_ray" if "rays" in rate else "boxes_per_query"
                row.append(f"{query_relative(q, kind, field, b, prefix):.2f}")
            rows.append(row)
    out += [table(["query", "share of nodes", "time b=4", "boxes b=4", "time b=8", "boxes b=8"], rows), ""]
    best = q["best"]
    out += ["Best b (highest median rate against b = 2, whole files): " +
            ", ".join(f"{title} **b = {best[kind]['branching']}**" for kind, _, title in QUERY_KINDS) + ".", ""]
    out += [f"![queries]({rel}/queries.png)", ""]
    whole = [r for r in q["experiment"] if r["prefix"] == 1.0 and r["branching"] == q["embree_branching"]]
    out += [f"Per mesh at b = {q['embree_branching']}, whole files, one thread:", "",
            table(["mesh", "triangles", "camera rays/s", "boxes / tris a ray", "random rays/s", "boxes / tris a ray",
                   "boxes/s", "nearest/s"],
                  [[r["mesh"], f"{r['triangles']:,}", f"{r['camera']['rays_per_second']:,.0f}",
                    f"{r['camera']['boxes_per_ray']:.1f} / {r['camera']['triangles_per_ray']:.1f}",
                    f"{r['random']['rays_per_second']:,.0f}",
                    f"{r['random']['boxes_per_ray']:.1f} / {r['random']['triangles_per_ray']:.1f}",
                    f"{r['boxes']['queries_per_second']:,.0f}", f"{r['nearest']['queries_per_second']:,.0f}"]
                   for r in whole]), ""]
    out += ["### Against Embree", "",
            f"Embree 3.13 (Debian's libembree-dev), `rtcIntersect1` and `rtcOccluded1` over a scene of the "
            f"file's triangles built at medium quality, the same rays, b = {q['embree_branching']}; times "
            "alternate with facetree's, medians. Agreement on every shared mesh (rays that hit different "
            "triangles, and hits whose t differ by more than 1e-5 relative):", "",
            table(["mesh", "camera: same triangle", "different", "t > 1e-5", "random: same triangle", "different",
                   "t > 1e-5", "worst t", "facetree's t from exact", "Embree's t from exact"],
                  [[a["mesh"], f"{a['camera']['same_triangle']:.6f}", a["camera"]["different_triangle"],
                    a["camera"]["t_outside_1e-5"], f"{a['random']['same_triangle']:.6f}",
                    a["random"]["different_triangle"], a["random"]["t_outside_1e-5"],
                    f"{max(a['camera']['worst_t_relative'], a['random']['worst_t_relative']):.1e}",
                    f"{max(a['camera']['facetree_worst_t_against_exact'], a['random']['facetree_worst_t_against_exact']):.1e}",
                    f"{max(a['camera']['embree_worst_t_against_exact'], a['random']['embree_worst_t_against_exact']):.1e}"
                    if "embree_worst_t_against_exact" in a["camera"] else ""]
                   for a in q["agreement"]]), "",
            "Where the two t differ by more than 1e-5, each is set against the exact t of its own triangle's "
            "plane (long double): the check `t_differences_embree_rounding` says whether Embree's is the one "
            "further from it every time. Where they hit different triangles, or their t differ by more than "
            "1e-5, both answers are tested exactly (long double): the check `facetree_exact_where_they_differ` "
            "says whether facetree's is the true nearest of the two triangles, or the t nearer its plane's, on "
            "every such ray.", ""]
    if q["speed"]:
        out += ["dragon_vrip, 1M rays of each kind (closest hit, any hit; facetree time over Embree's):", "",
                table(["threads", "rays", "facetree s", "Embree s", "ratio", "any: facetree s", "Embree s", "ratio",
                       "Embree build s", "facetree load s", "layout for rays s"],
                      [[r["threads"], kind, f"{r[kind]['closest_seconds']:.3f}", f"{r[kind]['embree_closest_seconds']:.3f}",
                        f"**{r[kind]['closest_ratio']:.2f}**", f"{r[kind]['any_seconds']:.3f}",
                        f"{r[kind]['embree_any_seconds']:.3f}", f"{r[kind]['any_ratio']:.2f}",
                        f"{r['embree_build_seconds']:.2f}", f"{r['load_seconds']:.2f}",
                        f"{r['layout_seconds']:.3f}" if "layout_seconds" in r else ""]
                       for r in q["speed"] for kind in ("camera", "random")]), ""]
    if q.get("reader"):
        r = q["reader"]
        out += [f"The 56M-face dragon's file ({r['file_bytes'] / 1e9:.2f} GB) through the lazy reader under "
                f"--memory {r['cap']}, two threads: camera rays {r['camera']['rays_per_second']:,.0f} a second, "
                f"random rays {r['random']['rays_per_second']:,.0f}; peak RSS {r['peak_rss_bytes'] / 2**20:.0f} MiB"
                + (f", the rays sent {r['batch']:,} at a time (a batch's rays and hits: "
                   f"{r['rays_bytes'] / 2**20:.1f} MiB)" if "batch" in r else
                   f", of which the 1M rays and their hits held by the benchmark "
                   f"{r['rays_bytes'] / 2**20:.0f} MiB" if "rays_bytes" in r else "")
                + (f"; the query index {r['index_seconds']:.1f} s, {r['index_temporary_bytes'] / 1e9:.2f} GB of "
                   "temporary files (nodes by subtree, the triangles' corners)" if "index_seconds" in r else "")
                + ".", ""]
    checks = q["checks"]
    out += ["Checks: " + ", ".join(f"{k} {'yes' if v else '**no**'}" for k, v in checks.items()) + ".", ""]
    return out


def markdown(report, figures, rel):
    out = ["# Benchmarks", "",
           "Generated by `scripts/bench" + (" --quick" if report.get("quick") else "") + "` and `scripts/plot`; "
           "do not edit by hand. Each case ran " + str(report["repeat"]) + " times; medians. Ratios are taken "
           "per repetition from runs made back to back and then the median. The machine is shared: wall times "
           "carry the load of other work (load average below), process CPU times (user + system of the "
           "child, from wait4) much less, so ratios are given for both." +
           (" In `--quick` the Garland metric runs once per mesh (its heights are deterministic)."
            if report.get("quick") else ""), "",
           table(["", ""], [
               ["date", report["date"]], ["machine", report["machine"]],
               ["CPU", f"{report.get('cpu_model', '?')}, {report['cpus']} logical CPUs"],
               ["memory", f"{report['memory_bytes'] / 2**30:.1f} GiB" if report.get("memory_bytes") else "?"],
               ["load average at start / end", f"{report['load_average_start'][0]:.1f} / "
                                               f"{report.get('load_average_end', [float('nan')])[0]:.1f}"],
               ["bench wall time", f"{report.get('wall_seconds', 0) / 60:.1f} min"],
           ] + ([["wall time per section, min (load average at its end)", ", ".join(
               f"{name} {seconds / 60:.1f} ({report.get('section_load_average_end', {}).get(name, float('nan')):.1f})"
               for name, seconds in report["section_seconds"].items())]] if report.get("section_seconds") else []) + [
           ] + ([[f"sections {', '.join(k['sections'])}", f"kept from the run of {k['date']} (load "
                  f"{k['load_average_start'][0]:.1f} / {k['load_average_end'][0]:.1f}, "
                  f"{k['wall_seconds'] / 60:.1f} min)"]] if (k := report.get("kept_from")) and k.get("sections") else [])), ""]
    out += headline_markdown(report)

    if "rounds" in report:
        out += rounds_markdown(report["rounds"])

    if "octree" in report:
        o = report["octree"]
        out += ["## Face clustering against the octree baseline (Fig. 80)", "",
                "`facetree build MESH --method octree`: the tightest-fit octree of the seed's sec. 5.7.2 "
                "(octants of the bounding cube; a triangle larger than a child octant stays at the node; leaves "
                "of at most 8 triangles; tight axis-aligned boxes). Face clustering time is hierarchy and "
                "oriented boxes with side areas, without reading (`seconds.build - seconds.read`).", "",
                (f"**Median ratio over the meshes of 50k faces and more: {o['median_ratio']:.1f} (wall), "
                 f"{o['median_ratio_cpu']:.1f} (CPU).** " if o.get("median_ratio") else "")
                + "The seed reports about 2.5.", "",
                (f"In instructions (callgrind, which machine load does not move), on {o['instructions']['mesh']}: "
                 f"{o['instructions']['clustering'] / 1e6:.0f} M for the clustering, "
                 f"{o['instructions']['octree'] / 1e6:.0f} M for the octree: **ratio "
                 f"{o['instructions']['ratio']:.1f}**." if o.get("instructions") else ""), "",
                table(["mesh", "faces", "clustering s", "octree s", "ratio (wall)", "ratio (CPU)",
                       "ratio without boxes (wall)", "height cluster / octree"],
                      [[r["mesh"], f"{r['triangles']:,}", f"{r['cluster_seconds']:.3f}", f"{r['octree_seconds']:.3f}",
                        f"{r['ratio']:.1f}", f"{r['ratio_cpu']:.1f}", without_boxes(report, r),
                        f"{r['cluster_height']} / {r['octree_height']}"]
                       for r in sorted(o["rows"], key=lambda r: r["triangles"])]), "",
                "The two do different amounts of work per triangle. The octree makes one partition pass per "
                "level over 28-byte triangle records and takes each box as the union of its children's and its "
                "own triangles' boxes (O(nodes)). The face clustering evaluates every dual edge's cost, keeps "
                "a heap, merges edge lists, and computes oriented boxes whose extents are exact and never "
                "accumulated from children (O(n h) vertex scans) plus six side areas per node; the column "
                "without boxes takes the median box time out (same runs, medians).", "",
                f"![octree]({rel}/octree.png)", ""]

    if "balance" in report:
        b = report["balance"]
        out += ["## Balance: default metric against Garland's (Table 6, Fig. 73)", "",
                "Height = nodes on the longest root-to-face path, faces included; balanced = ceil(log2 n) + 1. "
                "Box time is the exact oriented boxes and side areas of every node (O(n h)).", "",
                table(["mesh", "faces", "balanced", "height default", "height Garland", "Garland / default",
                       "boxes s default", "boxes s Garland"],
                      [[r["mesh"], f"{r['triangles']:,}", r["balanced_height"], r["willmott"]["height"],
                        r["garland"]["height"] if r["garland"] else "skipped",
                        f"{r['garland_over_default_height']:.1f}" if r["garland"] else "",
                        f"{r['willmott']['boxes_seconds']:.3f}",
                        f"{r['garland']['boxes_seconds']:.3f}" if r["garland"] else ""]
                       for r in sorted(b["meshes"], key=lambda r: r["triangles"])]), "",
                f"![balance]({rel}/balance.png)", "",
                "Height for k in {0, 1e-5, 1e-4, 1e-3} (eq. 80; 1e-4 is the default), with the balance guard "
                "(`--balance-slack 1.5`, the default: a merge whose subtree would exceed 1.5x its balanced height "
                "is penalised) and without it (`--balance-slack 0`: Willmott's eq. 84 alone):", "",
                table(["mesh", "k", "guard", "height / balanced", "boxes s", "clustering s", "process CPU s",
                       "max degree"],
                      [[r["mesh"], f"{r['k']:g}", "on" if r.get("balance_slack", 1.5) else "off",
                        f"{r['height']} / {r['balanced_height']}",
                        f"{r['boxes_seconds']:.3f}", f"{r['cluster_seconds']:.3f}",
                        f"{r.get('process_cpu_seconds', float('nan')):.3f}", r["max_degree"]]
                       for r in b["k"]]), "",
                f"![k]({rel}/balance_k.png)", ""]
        if b.get("pictures"):
            cuts = sorted({(p["mesh"], p["cut"]) for p in b["pictures"]})
            out += [f"![clusters]({rel}/clusters.png)", "",
                    "`facetree render FILE.fch --cut N`, one colour per cluster, the same N for both metrics: 64 "
                    "clusters below the joins of the mesh's components (" +
                    ", ".join(f"{mesh} N = {cut}" for mesh, cut in cuts) + ").", ""]

    if "profile" in report:
        rows = report["profile"]
        out += ["## Profile (Tables 5 and 8)", "",
                f"{rows[0]['mesh']}, {rows[0]['triangles']:,} triangles; phases from `build --json` (wall, median). "
                "The eigensolver is timed inside the initial costs and the merge loop (sampled) and shown as its own "
                "row, taken out of the merge loop; costs evaluated during the merge loop are not timed apart from it.",
                ""]
        header = ["phase"] + [f"{METRIC_LABEL[r['metric']]} s" for r in rows] + [f"{METRIC_LABEL[r['metric']]} %" for r in rows]
        body = []
        for key, label in rows[0]["phase_labels"]:
            body.append([label] + [f"{r['phases'][key]:.3f}" for r in rows] +
                        [f"{100 * r['phases'][key] / r['total']:.0f}%" for r in rows])
        body.append(["**total without reading**"] + [f"**{r['total']:.3f}**" for r in rows] + ["100%" for r in rows])
        body.append(["PCA solves / normals from S"] + [f"{r['eigen_solves']:,} / {r['normal_shortcuts']:,}" for r in rows]
                    + ["" for r in rows])
        out += [table(header, body), "", f"![profile]({rel}/profile.png)", ""]

    if "scaling" in report:
        out += scaling_markdown(report["scaling"], rel)

    if "flat" in report:
        f = report["flat"]
        out += ["## Flat grids (Figs 69-71)", "",
                "Regular triangulated grids (`facetree gen grid`), no boxes. Log-log slope of time: " +
                ", ".join(f"**{METRIC_LABEL[m]} {v:.2f}**" for m, v in f["slopes"].items()) + ".", "",
                table(["metric", "triangles", "seconds", "max degree", "average degree", "height / balanced"],
                      [[METRIC_LABEL[r["metric"]], f"{r['triangles']:,}", f"{r['seconds']:.3f}", r["max_degree"],
                        f"{r['average_degree']:.2f}", f"{r['height']} / {r['balanced_height']}"] for r in f["rows"]]), "",
                f"![flat]({rel}/flat.png)", ""]

    if "branching" in report:
        br = report["branching"]
        out += ["## Branching factor and truncation", "",
                table(["mesh", "b", "MB", "nodes", "height", "verified"],
                      [[r["mesh"], r["branching"], f"{r['bytes'] / 1e6:.2f}", f"{r['nodes']:,}", r["height"],
                        "yes" if r["verified"] else "**no**"] for r in br["sizes"]]), "",
                "Prefixes of the b = 2 file (`facetree truncate --nodes N`): the geometry travels with every "
                "prefix, so small prefixes cost the mesh plus little.", "",
                table(["mesh", "nodes", "MB", "share of nodes", "share of bytes"],
                      [[p["mesh"], f"{p['nodes']:,}", f"{p['bytes'] / 1e6:.2f}", f"{p['fraction_of_nodes']:.4f}",
                        f"{p['fraction_of_bytes']:.3f}"] for p in br["prefixes"]]), "",
                f"![branching]({rel}/branching.png)", ""]

    if "read" in report:
        out += ["## Reading", "",
                table(["mesh", "faces", "s", "MB/s", "M faces/s", "peak MiB", "x of zstd -dc"],
                      [[r["mesh"], f"{r['faces']:,}", f"{r['seconds']:.3f}", f"{r['mb_per_second']:.1f}",
                        f"{r['faces_per_second'] / 1e6:.2f}", mib(r["peak_rss_bytes"]), f"{r['ratio_to_zstd']:.2f}"]
                       for r in report["read"]]), ""]

    if "outofcore" in report:
        out += outofcore_markdown(report["outofcore"], rel)
    if "queries" in report:
        out += queries_markdown(report["queries"], rel)
    out += ["## Regenerating", "",
            "```sh",
            "scripts/bench --quick        # or without --quick: every shared mesh, larger generated ones",
            "scripts/plot                 # JSON of the last run -> docs/figures/*.png + docs/benchmarks.md",
            "# one section, the others kept from an earlier report:",
            "scripts/bench --quick --only outofcore --keep-from OLD/bench.json",
            "```", ""]
    return "\n".join(out)


def headline_markdown(report):
    """The ratios the sections below lead to, in one list."""
    lines = []
    if (o := report.get("octree")) and o.get("median_ratio"):
        lines.append(f"Face clustering / tightest-fit octree time, median over the meshes of 50k faces and more: "
                     f"**{o['median_ratio']:.1f}** (wall), **{o['median_ratio_cpu']:.1f}** (CPU)"
                     + (f"; **{o['instructions']['ratio']:.1f}** in instructions on {o['instructions']['mesh']}"
                        if o.get("instructions") else "") + " (the seed: about 2.5).")
    if b := report.get("balance"):
        heights = [f"{r['mesh']} {r['willmott']['height']} against {r['garland']['height']} "
                   f"(x{r['garland_over_default_height']:.1f}, balanced {r['balanced_height']})"
                   for r in b["meshes"] if r["mesh"] in ("dragon_vrip", "openfoam_buildings") and r.get("garland")]
        if heights:
            lines.append("Height, default metric against Garland's: **" + "**, **".join(heights) + "**.")
    if f := report.get("flat"):
        lines.append("Flat grids, log-log slope of time: " +
                     ", ".join(f"{METRIC_LABEL[m]} **{v:.2f}**" for m, v in f["slopes"].items()) + ".")
    if s := report.get("scaling"):
        line = (f"Scaling, log-log slopes over the in-core builds: time **{s['slope_time']:.2f}** (wall), "
                f"**{s['slope_cpu']:.2f}** (CPU), peak RSS **{s['slope_rss']:.2f}** (from 10k faces; "
                f"**{large_rss_slope(s):.2f}** from {count_label(LARGE_FACES)}, past the process's fixed base)")
        if w := s.get("with_out_of_core"):
            line += f"; with the out-of-core point: time **{w['time']:.2f}** (wall), **{w['cpu']:.2f}** (CPU)"
        lines.append(line + ".")
        for p in (p for p in s["points"] if p.get("memory")):
            lines.append(f"{p['mesh']} ({p['faces']:,} faces) out of core under --memory {p['memory']}: "
                         f"**{p['process_wall_seconds'] / 60:.1f} min** wall, {p['process_cpu_seconds'] / 60:.1f} "
                         f"CPU min, peak RSS **{p['peak_rss_bytes'] / 2**20:.0f} MiB**.")
    if (o := report.get("outofcore")) and o.get("rows"):
        parts = []
        for order in ("coherent", "shuffled"):
            rows = [r for r in o["rows"] if r["input"] == order and r["memory"]]
            if rows:
                parts.append(f"{order} " + ", ".join(
                    f"{r['memory']} x{r['ratio']['seconds']:.2f} ({r['ratio']['process_cpu_seconds']:.2f} CPU, "
                    f"RSS x{r['ratio']['process_peak_rss_bytes']:.2f})" for r in rows))
        lines.append(f"Out of core / in core on terrain {o['faces'] / 1e6:g}M, time (wall): **" +
                     "**; **".join(parts) + "**.")
    return (["## Headline figures", ""] + [f"- {line}" for line in lines] + [""]) if lines else []


def scaling_markdown(s, rel):
    capped = [p for p in s["points"] if p.get("memory")]
    w = s.get("with_out_of_core")
    large = [p for p in s["points"] if p["faces"] >= LARGE_FACES and not p.get("memory")]
    large_time, large_cpu, large_rss = (loglog_slope([(p["faces"], p[key]) for p in large])
                                        for key in ("cluster_seconds", "process_cpu_seconds", "peak_rss_bytes"))
    out = ["## Scaling (Figs 77-78)", "",
           f"Log-log slopes over the in-core builds of 10k faces and more: **time {s['slope_time']:.2f} (wall), "
           f"{s['slope_cpu']:.2f} (process CPU), peak RSS {s['slope_rss']:.2f}**"
           + (f"; with the out-of-core point: time {w['time']:.2f} (wall), {w['cpu']:.2f} (process CPU), "
              f"peak RSS {w['rss']:.2f} (bounded by its cap, not a memory scaling)" if w else "") + ". "
           "Slope 1 is O(n) (O(n log n) looks the same), 1.5 the seed's unbalanced worst case. Generated "
           "meshes: `facetree gen terrain`. Clustering time is hierarchy and boxes without reading. Peak RSS "
           "below 100k faces is mostly the process's fixed ~17.5 MiB, which flattens its fit: over the in-core "
           f"builds of {count_label(LARGE_FACES)} faces and more its slope is **{large_rss:.2f}** (time "
           f"{large_time:.2f} wall, {large_cpu:.2f} CPU). Wall times carry the machine's load at the moment each "
           "build ran, which varies over a run (see the load per section in the header): the CPU slope is the "
           "one to read.",
           ""]
    if capped:
        out += [" ".join(
            f"**{p['mesh']} ({p['faces']:,} faces) is built out of core** (`facetree build MESH -o OUT.fch "
            f"--memory {p['memory']} --tmp DIR --json`), in the full run only (`--quick` skips it) and once: the tree is deterministic and the run takes "
            f"{p['process_wall_seconds'] / 60:.1f} minutes (in core it would need ~8.6 GB and ~12 minutes). "
            f"Its time is the job's total less its read (bin {p['phases']['bin']:.1f} s, cells "
            f"{p['phases']['cells']:.1f} s, merge {p['phases']['merge']:.1f} s, write {p['phases']['write']:.1f} s: "
            "the write computes the boxes and compresses the file, which the in-core points do not write), "
            f"its peak RSS the process's under the cap ({p['cells']:,} cells, {p['leaves']:,} leaf clusters, "
            f"height {p['height']} / {p['balanced_height']}, temporary peak "
            f"{p['temporary_bytes_peak'] / 1e9:.1f} GB, file {p['file_bytes'] / 1e9:.2f} GB). It is left out of "
            "the fit: a different build whose memory is bounded by the cap. It is the star in the figure; its "
            "dual-edge degrees are not reported by the out-of-core job." for p in capped), ""]
    out += [table(["mesh", "faces", "build", "clustering s", "process CPU s", "peak RSS MiB", "bytes / face",
                   "average degree", "max degree"],
                  [[p["mesh"], f"{p['faces']:,}",
                    f"out of core, --memory {p['memory']}, 1 run" if p.get("memory") else "in core",
                    f"{p['cluster_seconds']:.3f}", f"{p['process_cpu_seconds']:.3f}",
                    mib(p["peak_rss_bytes"]), f"{p['peak_rss_bytes'] / p['faces']:.0f}",
                    f"{p['average_degree']:.2f}" if p.get("average_degree") is not None else "-",
                    p["max_degree"] if p.get("max_degree") is not None else "-"] for p in s["points"]]), "",
            f"![scaling]({rel}/scaling.png)", ""]
    return out


def rounds_markdown(rows):
    """The merge in rounds against the exact greedy order (bench section rounds)."""
    def fit(r, cut):
        v = r["fit_ratio"].get(str(cut), r["fit_ratio"].get(cut))
        return "-" if v is None else f"{v:.3f}"
    out = ["## The merge in rounds against the exact greedy order", "",
           "`facetree build MESH -o OUT.fch --json` with the default order (rounds of reciprocal cheapest pairs) "
           "and default threads, with `--threads 1`, with `--order exact`, and `build --method octree`, "
           "interleaved per repetition; whole processes (wall, peak RSS from wait4). Phases of the default run "
           "from `--json`. Fit: the sum of area x eFit over cuts of 1,000 and 100,000 clusters "
           "(`info --fit-cuts`), rounds / exact (lower is better; `-` where the mesh has fewer faces). "
           "Same bytes: the default run's file equals `--threads 1`'s.", "",
           table(["mesh", "faces", "s", "1 thread", "exact", "octree", "init", "cost", "merge", "boxes", "write",
                  "rounds", "peak MiB", "height / balanced", "fit 1k", "fit 100k", "x of exact", "x of octree",
                  "same bytes", "missed"],
                 [[r["mesh"], f"{r['triangles']:,}", f"{r['rounds']['wall_seconds']:.2f}",
                   f"{r['one']['wall_seconds']:.2f}", f"{r['exact']['wall_seconds']:.2f}",
                   f"{r['octree']['wall_seconds']:.2f}"] +
                  [f"{r['rounds']['phases'][k]:.2f}" for k in ("init", "cost", "merge", "boxes", "write")] +
                  [r["round_count"], mib(r["rounds"]["peak_rss_bytes"]), f"{r['height']} / {r['balanced_height']}",
                   fit(r, 1000), fit(r, 100000), f"{r['ratio_to_exact']:.2f}", f"{r['ratio_to_octree']:.2f}",
                   "yes" if r["same_bytes_threads_1_and_default"] else "**no**",
                   ", ".join(k for k, ok in r["checks"].items() if not ok) or "-"] for r in rows]), ""]
    if any("top_fit_ratio" in r for r in rows):
        def cell(values, cut, digits=2):
            v = (values or {}).get(str(cut), (values or {}).get(cut))
            return "-" if v is None else f"{v:.{digits}f}"
        cuts = (12, 100, 1000)
        every = next((r["top_every_cut"]["list"] for r in rows if "list" in r.get("top_every_cut", {})),
                     list(range(2, 65)))
        out += ["### The top of the tree: the first nodes, cut by cut", "",
                "What a truncated file keeps. Fit: the sum of area x eFit over the cut of 12, 100 and 1,000 "
                "clusters, the default build against eq. 84's order to the root (`--top 0`; lower is better). "
                "Boxes: the sum of the cut's box areas against as many runs of the faces in Morton order. "
                "Balance: the clusters of the cut of 100 under 1% of the average cluster's area, the default "
                f"build and `--top 0`. Every cut of {cut_list(every)} clusters: the worst fit over eq. 84's "
                f"order's and the worst boxes over the Morton runs', at that cut, and how many of the "
                f"{len(every)} cuts are over 1.10 in fit and over 1.0 in boxes.", "",
                table(["mesh", "faces"] + [f"fit {c}" for c in cuts] + [f"boxes {c}" for c in cuts] +
                      ["small of 100", "small of 100, --top 0", f"cuts {every[0]}-{every[-1]}: worst fit (cut)",
                       "over 1.10",
                       "worst boxes (cut)", "over 1.0"],
                      [[r["mesh"], f"{r['triangles']:,}"] + [cell(r.get("top_fit_ratio"), c, 3) for c in cuts] +
                       [cell(r.get("box_ratio", {}).get("rounds"), c) for c in cuts] +
                       [str(r.get("small_clusters", {}).get("rounds", "-")),
                        str(r.get("small_clusters", {}).get("eq84", "-"))] + every_cells(r.get("top_every_cut"))
                       for r in rows]), ""]
    return out


def cut_list(cuts):
    """Cuts as text, runs of consecutive ones as ranges: 2 to 64, 80, 100 and 128."""
    parts, start = [], 0
    for i in range(1, len(cuts) + 1):
        if i == len(cuts) or cuts[i] != cuts[i - 1] + 1:
            run = cuts[start:i]
            parts += [f"{run[0]} to {run[-1]}"] if len(run) > 2 else [str(c) for c in run]
            start = i
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]


def every_cells(e):
    """The worst fit and boxes over the top's cuts (bench_rounds' top_every_cut)."""
    if not e or e.get("fit") is None:
        return ["-"] * 4
    return [f"{e['fit']:.2f} ({e['fit_cut']})", str(e["fit_over"]), f"{e['boxes']:.2f} ({e['boxes_cut']})",
            str(e["boxes_over"])]


def outofcore_markdown(o, rel):
    rows, quality = o["rows"], o["quality"]
    first = rows[0]
    cuts = [str(n) for n in o["fit_cuts"]]
    ooc = [r for r in rows if r["out_of_core"]]
    quality_ooc = [r for r in quality if r["cell_faces"] is not None]
    worst_fit = {n: max(r["ratio"]["sum_fit"][n] for r in quality_ooc) for n in cuts} if quality_ooc else {}
    out = ["## Out of core", "",
           f"`facetree build MESH -o OUT.fch --memory CAP --tmp DIR --json` on `facetree gen terrain -n "
           f"{o['faces']:,}` ({first['triangles']:,} faces) and its shuffled twin (`--shuffle-vertices "
           f"--shuffle-faces`). In core is `--memory {o['in_core_cap']}`: the job's in-core path (without "
           "`--memory` the CLI takes its older in-core path, which has no job report). "
           f"{o['repeat']} run{'s' if o['repeat'] > 1 else ''} per case"
           f"{' (medians)' if o['repeat'] > 1 else ''}; section run at {o['date']}, load "
           f"{o['load_average_start'][0]:.1f} / {o['load_average_end'][0]:.1f}, {o['wall_seconds'] / 60:.1f} min. "
           "Peak RSS: the process's own (wait4's ru_maxrss, what `/usr/bin/time` prints) and the job's report. "
           "Out-of-core files are written at zstd level 3, in-core ones at 9 (the job's defaults). The trees "
           "are deterministic, hence one run per case even in the full run, whose 8 builds of 10M faces take "
           "70-180 CPU seconds each: 10M is the largest terrain whose in-core reference fits the full run's "
           "hour. The 50M terrain of the scaling section is built at --memory 1G only (in core it needs "
           "~8.6 GB)." + "".join(
               f" **Over the cap: {r['input']} at --memory {r['memory']} peaked at "
               f"{r['process_peak_rss_bytes'] / 2**20:.1f} MiB.**" for r in rows if not r["under_cap"]), "",
           table(["input", "--memory", "out of core", "s (wall)", "process CPU s", "peak RSS MiB", "job peak MiB",
                  "under cap", "temporary MB", "file MB", "cells", "leaves", "height / balanced"],
                 [[r["input"], cap_label(r["memory"]), "yes" if r["out_of_core"] else "no", f"{r['seconds']:.2f}",
                   f"{r['process_cpu_seconds']:.2f}", mib(r["process_peak_rss_bytes"]), mib(r["peak_rss_bytes"]),
                   "yes" if r["under_cap"] else "**no**", f"{r['temporary_bytes_peak'] / 1e6:.1f}",
                   f"{r['file_bytes'] / 1e6:.1f}", f"{r['cells']:,}", f"{r['leaves']:,}",
                   f"{r['height']} / {r['balanced_height']}"] for r in rows]), "",
           "Ratios to the in-core build of the same input:", "",
           table(["input", "--memory", "time (wall)", "process CPU", "peak RSS", "file bytes", "height"],
                 [[r["input"], cap_label(r["memory"])] +
                  [f"{r['ratio'][k]:.2f}" for k in ("seconds", "process_cpu_seconds", "process_peak_rss_bytes",
                                                   "file_bytes", "height")]
                  for r in rows if r["memory"]]), ""]
    if ooc:
        phases = [k for k in ("read", "bin", "cells", "merge", "write") if k in ooc[0]["phases"]]
        out += ["Out-of-core phases (seconds, from the job's report):", "",
                table(["input", "--memory"] + phases + ["total"],
                      [[r["input"], cap_label(r["memory"])] + [f"{r['phases'][k]:.2f}" for k in phases + ["total"]]
                       for r in ooc]), ""]
    if o.get("dragons"):
        out += ["### The subdivided dragon", "",
                "`facetree gen subdivide dragon_vrip.ply.zst --levels L` (coherent, and with `--shuffle-vertices "
                "--shuffle-faces`), then `facetree build MESH -o OUT.fch --memory CAP --tmp DIR --json`, one run "
                "each. Checks: the targets of `DRAGON_TARGETS` in scripts/bench.py.", "",
                table(["faces", "input", "--memory", "s (wall)", "M faces/s", "CPU use"] +
                      [k for k in ("read", "bin", "cells", "merge", "write")] +
                      ["peak RSS MiB", "temporary MB", "file MB", "temporary / file", "checks"],
                      [[f"{r['triangles']:,}", r["input"], r["memory"], f"{r['seconds']:.1f}",
                        f"{r['faces_per_second'] / 1e6:.2f}", f"{r['cpu_use'] * 100:.0f}%"] +
                       [f"{r['phases'].get(k, 0):.1f}" for k in ("read", "bin", "cells", "merge", "write")] +
                       [mib(r["peak_rss_bytes"]), f"{r['temporary_bytes_peak'] / 1e6:.0f}",
                        f"{r['file_bytes'] / 1e6:.0f}", f"{r['temporary_over_file']:.2f}",
                        " ".join(f"{k} {'ok' if v else '**missed**'}" for k, v in r["checks"].items())]
                       for r in o["dragons"]]), ""]
    if o.get("cap_quality"):
        cuts_cap = list(o["cap_quality"][0]["fit_ratio"])
        every = lambda r: r.get("every_cut", {})
        out += ["### Shared meshes out of core under a small cap, and meshes of many pieces", "",
                "Built in core and at the cap, then `facetree info OUT.fch --fit-cuts`: sum of area x eFit over "
                "the cut and heights, out of core / in core (checks: fits within 10%, heights within 1.25x, "
                "and every cut of 2-64, 80-512 and 1,000 within 10%: how many are over, the worst).", "",
                table(["mesh", "--memory", "height (in core / out of core)", "height ratio"] +
                      [f"fit ratio, {int(n):,}" for n in cuts_cap] + ["every cut: over 1.10", "worst (cut)"] +
                      ["checks"],
                      [[r["mesh"], r["memory"], f"{r['in_core']['height']} / {r['out_of_core']['height']}",
                        f"{r['height_ratio']:.3f}"] + [f"{r['fit_ratio'][n]:.3f}" for n in cuts_cap] +
                       [f"{every(r).get('fit_over', 0)} of {len(every(r).get('list', []))}",
                        f"{every(r).get('fit') or 0:.2f} ({every(r).get('fit_cut')})"] +
                       [" ".join(f"{k} {'ok' if v else '**missed**'}" for k, v in r["checks"].items())]
                       for r in o["cap_quality"]]), ""]
    out += ["### Quality: out of core against in core on meshes that fit", "",
            "Each mesh built in core and out of core forced with cells of at most N faces (`--cell-faces N`), "
            f"then `facetree info OUT.fch --fit-cuts {','.join(cuts)}`: the cut is the shortest prefix of the "
            "file giving at least that many clusters (what a truncated file or `render --cut` shows), and its "
            "fit error the sum over its clusters of eq. 84's eFit (the variance of the surface along the "
            "cluster's normal) and of area x eFit (the squared distance to the cluster's plane integrated over "
            "the surface). Lower is better. The target: within 10% of in core." +
            (" **Largest ratio of sum eFit: " + ", ".join(f"{worst_fit[n]:.2f} at {int(n):,} clusters" for n in cuts)
             + ".**" if worst_fit else ""), "",
            table(["mesh", "faces", "build", "cells / leaves", "height / balanced"] +
                  [f"sum eFit, {int(n):,}" for n in cuts] + [f"sum area x eFit, {int(n):,}" for n in cuts],
                  [[r["mesh"], f"{r['triangles']:,}",
                    "in core" if r["cell_faces"] is None else f"cells of {r['cell_faces']:,}",
                    f"{r['cells']:,} / {r['leaves']:,}", f"{r['height']} / {r['balanced_height']}"] +
                   [f"{r['cuts'][n]['sum_fit']:.4g}" for n in cuts] + [f"{r['cuts'][n]['sum_area_fit']:.4g}" for n in cuts]
                   for r in quality]), "",
            "Ratios out of core / in core:", "",
            table(["mesh", "build", "height"] + [f"sum eFit, {int(n):,}" for n in cuts] +
                  [f"sum area x eFit, {int(n):,}" for n in cuts],
                  [[r["mesh"], f"cells of {r['cell_faces']:,}", f"{r['ratio']['height']:.3f}"] +
                   [f"{r['ratio']['sum_fit'][n]:.3f}" for n in cuts] +
                   [f"{r['ratio']['sum_area_fit'][n]:.3f}" for n in cuts] for r in quality_ooc]), "",
            f"![outofcore]({rel}/outofcore.png)", ""]
    return out


HISTORY_MARKER = "<!-- history: written by hand, kept by scripts/plot -->"


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--json", required=True)
    parser.add_argument("--figures", required=True)
    parser.add_argument("--markdown", required=True)
    args = parser.parse_args()
    report = json.loads(pathlib.Path(args.json).read_text())
    figures = pathlib.Path(args.figures)
    figures.mkdir(parents=True, exist_ok=True)
    if "profile" in report:
        plot_profile(report["profile"], figures / "profile.png")
    if "balance" in report:
        plot_balance(report["balance"], figures / "balance.png")
        plot_k(report["balance"]["k"], figures / "balance_k.png")
        if report["balance"].get("pictures"):
            plot_pictures(report["balance"]["pictures"], figures / "clusters.png")
    if "scaling" in report:
        plot_scaling(report["scaling"], figures / "scaling.png")
    if "octree" in report:
        plot_octree(report["octree"], figures / "octree.png")
    if "branching" in report:
        plot_branching(report["branching"], figures / "branching.png")
    if "flat" in report:
        plot_flat(report["flat"], figures / "flat.png")
    if "queries" in report:
        plot_queries(report["queries"], figures / "queries.png")
    if "outofcore" in report and report["outofcore"].get("rows"):
        plot_outofcore(report["outofcore"], figures / "outofcore.png")
    md = pathlib.Path(args.markdown)
    rel = os.path.relpath(figures, md.parent)
    # The hand-written history below HISTORY_MARKER stays as it is.
    kept = ""
    if md.exists():
        old = md.read_text()
        if HISTORY_MARKER in old:
            kept = "\n" + old[old.index(HISTORY_MARKER):]
    md.write_text(markdown(report, figures, rel) + kept)
    print(f"plot: {md}")


if __name__ == "__main__":
    main()
