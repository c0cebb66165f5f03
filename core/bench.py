"""``python -m core bench`` and ``python -m core demo``: every strategy over a camera
path in one process, measured against the object-ID truth.

Per strategy, over the whole path: median and p95 frame ms, culling overhead
(traversal + queries), triangles drawn and the render rate, queries issued and
skipped by the occupancy map, query rectangle pixels, false negatives and R/V'
(objects kept over objects truly visible).  Speed-ups are ratios within one run.
"""

import json
import os
import resource
import sys
import time

import numpy as np

from .engine import DEFAULT_RESOLUTION, Culler, parse_resolution
from .errors import OccError
from .strategies import STRATEGIES
from .traversal import Visibility

TABLE_COLUMNS = (
    ("strategy", "{:<13}"), ("median ms", "{:>9.2f}"), ("p95 ms", "{:>8.2f}"),
    ("cpu ms", "{:>7.2f}"), ("GL calls", "{:>8.1f}"), ("reads", "{:>6.1f}"),
    ("triangles", "{:>11.0f}"), ("render %", "{:>8.2f}"),
    ("queries", "{:>8.1f}"), ("skipped", "{:>8.1f}"), ("query px", "{:>10.0f}"),
    ("FN", "{:>4d}"), ("R/V'", "{:>6.2f}"), ("x vfc", "{:>6.2f}"), ("x stopwait", "{:>10.2f}"),
)
# cpu ms: the pass's time outside GL calls; GL calls and reads (blocking read-backs)
# a frame from the renderer's counters (nan where the renderer does not count);
# query px: pixels the query boxes rasterise (their projected outlines, as the 2003
# paper counts them), the screen rectangles' pixels are in the JSON (query_rect_pixels).


def peak_rss_mb():
    """Peak resident memory of this process so far, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_bench(scene, cameras, strategies, resolution=DEFAULT_RESOLUTION, warmup=1, culler_kw=None,
              progress=None):
    """Run every strategy over ``cameras``; returns the report dict (the ``--json`` shape)."""
    unknown = [s for s in strategies if s not in STRATEGIES]
    if unknown:
        raise OccError(f"unknown strategies {unknown}; choose from {', '.join(STRATEGIES)}")
    culler = Culler(scene, resolution, strategy=strategies[0], **(culler_kw or {}))
    try:
        truths = [culler.truth(cam) for cam in cameras]
        tri_total = int(scene.triangle_counts.sum())
        report = {"objects": len(scene), "triangles_total": tri_total, "frames": len(cameras),
                  "resolution": list(resolution), "device": culler.renderer.device,
                  "strategies": {}}
        for name in strategies:
            culler.set_strategy(name)
            for cam, truth in zip(cameras[:warmup], truths, strict=False):   # compile, warm caches
                culler.cull(cam, truth=truth)
            culler.set_strategy(name)
            rows = []
            for cam, truth in zip(cameras, truths, strict=True):
                r = culler.cull(cam, truth=truth)
                fn = int((truth & ~r.visible).sum())
                rows.append({**r.stats, "false_negatives": fn, "truly_visible": int(truth.sum())})
            report["strategies"][name] = summarise(rows, tri_total)
            report["strategies"][name]["peak_rss_mb"] = round(peak_rss_mb(), 1)
            report["strategies"][name]["per_frame"] = {
                "frame_ms": [round(x["total_ms"], 3) for x in rows],
                "triangles": [x["triangles_drawn"] for x in rows]}
            if progress:
                progress(name, report["strategies"][name])
        add_speedups(report["strategies"])
        return report
    finally:
        culler.close()


HIERARCHY_COLUMNS = (
    ("builder", "{:<16}"), ("inner", "{:>7d}"), ("leaves", "{:>7d}"), ("units", "{:>7d}"),
    ("build s", "{:>8.2f}"), ("mem MB", "{:>7.1f}"), ("frustum ms", "{:>10.2f}"), ("occlusion ms", "{:>12.2f}"),
    ("draw ms", "{:>8.2f}"), ("render %", "{:>8.2f}"), ("fps", "{:>7.1f}"), ("median ms", "{:>9.2f}"),
    ("FN", "{:>4d}"),
)


def run_hierarchies(scene, cameras, builders, resolution=DEFAULT_RESOLUTION, strategy=None,
                    chunk_triangles=None, progress=None):
    """The seed's Appendix A table: per builder, nodes, build time and per-frame times."""
    from .hierarchy_choice import build_culler
    # hierarchies are compared under a strategy that always tests (auto may not)
    strategy = strategy or "om_coherent"
    tri_total = int(scene.triangle_counts.sum())
    report = {"objects": len(scene), "triangles_total": tri_total, "frames": len(cameras),
              "resolution": list(resolution), "strategy": strategy, "hierarchies": {}}
    truths = None
    for name in builders:
        t = time.perf_counter()
        culler, chosen = build_culler(scene, resolution, strategy, name, cameras, chunk_triangles)
        build_s = time.perf_counter() - t
        try:
            report["device"] = culler.renderer.device
            if truths is None:
                truths = [culler.truth(cam) for cam in cameras]
            culler.cull(cameras[0])                                      # warm-up
            culler.set_strategy(strategy)
            rows = []
            for cam, truth in zip(cameras, truths, strict=True):
                r = culler.cull(cam, truth=truth)
                rows.append({**r.stats, "false_negatives": int((truth & ~r.visible).sum()),
                             "truly_visible": int(truth.sum())})
            h = culler.hierarchy
            s = summarise(rows, tri_total)
            s.update({"builder": chosen, "inner_nodes": int((~h.is_leaf).sum()),
                      "leaf_nodes": int(h.is_leaf.sum()), "units": len(culler.units),
                      "build_s": build_s, "structure_mb": culler.structure_mb(),
                      "frustum_ms": float(np.mean([x["frustum_ms"] for x in rows])),
                      "occlusion_ms": float(np.mean([x["traversal_ms"] + x["query_ms"]
                                                     - x["frustum_ms"] for x in rows])),
                      "fps": 1e3 / max(s["frame_ms_median"], 1e-9)})
            report["hierarchies"][name] = s
            if progress:
                progress(name, s)
        finally:
            culler.close()
    return report


def format_hierarchy_table(report, title=""):
    head = " ".join(fmt.replace(".2f", "").replace(".1f", "").replace("d}", "}").format(name)
                    for name, fmt in HIERARCHY_COLUMNS)
    lines = [title, f"{report['objects']} objects, {report['triangles_total']:,} triangles, "
             f"{report['frames']} frames, strategy {report['strategy']}", head, "-" * len(head)]
    for name, s in report["hierarchies"].items():
        label = name if s["builder"] == name else f"{name}:{s['builder']}"
        vals = [label, s["inner_nodes"], s["leaf_nodes"], s["units"], s["build_s"], s["structure_mb"], s["frustum_ms"],
                s["occlusion_ms"], s["draw_ms"], s["render_rate"], s["fps"], s["frame_ms_median"],
                s["false_negatives"]]
        lines.append(" ".join(fmt.format(v) for (_, fmt), v in zip(HIERARCHY_COLUMNS, vals, strict=True)))
    return "\n".join(lines)


def summarise(rows, tri_total):
    """Aggregate per-frame stats into one row of the table."""
    ms = np.array([x["total_ms"] for x in rows])
    mean = {k: float(np.mean([x.get(k, 0) for x in rows])) for k in
            ("triangles_drawn", "queries", "queries_skipped", "query_rect_pixels", "query_raster_pixels",
             "traversal_ms", "query_ms", "draw_ms", "cpu_ms", "gl_ms", "visible", "truly_visible",
             "multiple_queries", "nodes_visited", "fresh")}
    counted = {k: (float(np.mean([x[k] for x in rows])) if all(x.get(k, -1) >= 0 for x in rows) else None)
               for k in ("gl_calls", "blocking_reads")}
    kept = sum(x["visible"] for x in rows)
    seen = sum(x["truly_visible"] for x in rows)
    return {
        "frame_ms_median": float(np.median(ms)),
        "frame_ms_p95": float(np.percentile(ms, 95)),
        "culling_ms": mean["traversal_ms"] + mean["query_ms"],
        "traversal_ms": mean["traversal_ms"], "query_ms": mean["query_ms"],
        "draw_ms": mean["draw_ms"],
        "cpu_ms": mean["cpu_ms"], "cpu_ms_median": float(np.median([x.get("cpu_ms", 0.0) for x in rows])),
        "gl_ms": mean["gl_ms"],
        "gl_calls": counted["gl_calls"], "blocking_reads": counted["blocking_reads"],
        "triangles": mean["triangles_drawn"],
        "render_rate": 100.0 * mean["triangles_drawn"] / max(tri_total, 1),
        "queries": mean["queries"], "queries_skipped": mean["queries_skipped"],
        "multiple_queries": mean["multiple_queries"],
        "query_pixels": mean["query_raster_pixels"],
        "query_rect_pixels": mean["query_rect_pixels"],
        "nodes_visited": mean["nodes_visited"], "fresh_passes": mean["fresh"],
        "false_negatives": int(sum(x["false_negatives"] for x in rows)),
        "conservativity": kept / max(seen, 1),
        "objects_kept": mean["visible"], "objects_truly_visible": mean["truly_visible"],
    }


def add_speedups(strategies):
    for base in ("vfc", "stopwait"):
        if base in strategies:
            ref = strategies[base]["frame_ms_median"]
            for row in strategies.values():
                row[f"speedup_over_{base}"] = ref / max(row["frame_ms_median"], 1e-9)


def format_table(report, title=""):
    head = " ".join(fmt.replace(".2f", "").replace(".0f", "").replace(".1f", "")
                    .replace("d}", "}").format(name) for name, fmt in TABLE_COLUMNS)
    lines = [title, f"{report['objects']} objects, {report['triangles_total']:,} triangles, "
             f"{report['frames']} frames at {report['resolution'][0]}x{report['resolution'][1]}, "
             f"device: {report['device']}", head, "-" * len(head)]
    for name, s in report["strategies"].items():
        nan = float("nan")
        vals = [name, s["frame_ms_median"], s["frame_ms_p95"], s.get("cpu_ms", nan),
                nan if s.get("gl_calls") is None else s["gl_calls"],
                nan if s.get("blocking_reads") is None else s["blocking_reads"],
                s["triangles"], s["render_rate"], s["queries"], s["queries_skipped"], s["query_pixels"],
                s["false_negatives"], s["conservativity"], s.get("speedup_over_vfc", nan),
                s.get("speedup_over_stopwait", nan)]
        lines.append(" ".join(fmt.format(v) for (_, fmt), v in zip(TABLE_COLUMNS, vals, strict=True)))
    return "\n".join(line for line in lines if line is not None)


def write_plots(report, out_dir, title):
    """Frame time and triangles along the path per strategy (the papers' Figures 5-11)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise OccError("--plot needs matplotlib: pip install matplotlib") from None
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    for key, label in (("frame_ms", "frame time (ms)"), ("triangles", "triangles drawn")):
        fig, ax = plt.subplots(figsize=(8, 4))
        for name, s in report["strategies"].items():
            ax.plot(s["per_frame"][key], label=name)
        ax.set_xlabel("frame")
        ax.set_ylabel(label)
        ax.set_title(f"{title}: {label}")
        if key == "triangles":
            ax.set_yscale("symlog")
        ax.legend()
        fig.tight_layout()
        path = os.path.join(out_dir, f"{title}_{key}.png")
        fig.savefig(path, dpi=90)
        plt.close(fig)
        paths.append(path)
    return paths


def write_snapshot(scene, camera, out_dir, title, resolution, strategy="om_multi"):
    """One frame: the view coloured by state, the occluded objects x-rayed, the occupancy map."""
    from .images import STATE_COLOURS, colour_by_state, write_png
    os.makedirs(out_dir, exist_ok=True)
    with Culler(scene, resolution, strategy=strategy) as c:
        result = c.cull(camera)
        ids = c.renderer.object_ids(camera)
        hidden = np.flatnonzero(result.state == Visibility.OCCLUDED)
        xray = c.renderer.object_ids(camera, hidden)
    view = colour_by_state(ids, result.state)
    # x-ray: where occluded objects lie (red) over the visible view, dimmed
    xr = (view // 3).copy()
    xr[(xray >= 0)[::-1]] = STATE_COLOURS[Visibility.OCCLUDED]
    paths = {"view": os.path.join(out_dir, f"{title}_view.png"),
             "xray": os.path.join(out_dir, f"{title}_occluded_xray.png"),
             "occupancy": os.path.join(out_dir, f"{title}_occupancy.png")}
    write_png(paths["view"], view)
    write_png(paths["xray"], xr)
    write_png(paths["occupancy"], np.kron(np.where(result.occupancy[::-1], 255, 40).astype(np.uint8),
                                          np.ones((4, 4), np.uint8)))
    return paths


def bench_scene(spec, camera=None, strategies=STRATEGIES, resolution=DEFAULT_RESOLUTION,
                frames=None, out_dir=None, plot=False, snapshot=False, log=print):
    """Load a scene (file or sample name), run the benchmark, optionally write a report folder."""
    from .cli import load_job
    t = time.perf_counter()
    scene, cameras, title = load_job(spec, camera, frames)
    log(f"{title}: loaded {len(scene)} objects, {int(scene.triangle_counts.sum()):,} triangles "
        f"in {time.perf_counter() - t:.1f} s; {len(cameras)} frames")
    report = run_bench(scene, cameras, list(strategies), resolution,
                       progress=lambda n, s: log(f"  {n:<9} median {s['frame_ms_median']:.2f} ms"))
    report["scene"] = title
    table = format_table(report, f"== {title} ==")
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        with open(os.path.join(out_dir, f"{title}.json"), "w") as f:
            json.dump(report, f, indent=1)
        with open(os.path.join(out_dir, f"{title}.txt"), "w") as f:
            f.write(table + "\n")
        if plot:
            write_plots(report, out_dir, title)
        if snapshot:
            write_snapshot(scene, cameras[len(cameras) // 2], out_dir, title, resolution)
    return report, table


def cmd_bench(args):
    if args.hierarchies:
        return cmd_hierarchies(args)
    from .cli import log_for
    strategies = [s.strip() for s in args.strategies.split(",") if s.strip()]
    out = args.out or ((args.plot or args.snapshot) and "reports") or None
    log = log_for(args.json)
    report, table = bench_scene(args.scene, args.camera, strategies, parse_resolution(args.resolution),
                                args.frames, out, args.plot, args.snapshot, log)
    if args.json:
        slim = {**report, "strategies": {k: {kk: vv for kk, vv in v.items() if kk != "per_frame"}
                                         for k, v in report["strategies"].items()}}
        json.dump(slim, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        print(table)


def cmd_hierarchies(args):
    from .cli import load_job, log_for
    builders = [b.strip() for b in args.hierarchies.split(",") if b.strip()]
    scene, cameras, title = load_job(args.scene, args.camera, args.frames)
    log = log_for(args.json)
    report = run_hierarchies(scene, cameras, builders, parse_resolution(args.resolution),
                             progress=lambda n, s: log(f"  {n:<9} median {s['frame_ms_median']:.2f} ms"))
    report["scene"] = title
    table = format_hierarchy_table(report, f"== {title}: hierarchies ==")
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, f"{title}_hierarchies.json"), "w") as f:
            json.dump(report, f, indent=1)
        with open(os.path.join(args.out, f"{title}_hierarchies.txt"), "w") as f:
            f.write(table + "\n")
    if args.json:
        json.dump(report, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        print(table)


def cmd_demo(args):
    """The main job: generate the sample scene(s), benchmark them, write the report folder."""
    import sample_scenes
    names = sample_scenes.NAMES if args.all else ("city",)
    out = args.out
    tables = []
    for name in names:
        _, table = bench_scene(name, None, STRATEGIES, parse_resolution(args.resolution),
                               args.frames, out, plot=True, snapshot=True)
        print(table)
        tables.append(table)
    with open(os.path.join(out, "README.txt"), "w") as f:
        f.write("\n\n".join(tables) + "\n")
    print(f"report written to {out}/")


def add_commands(sub):
    res = f"{DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]}"
    b = sub.add_parser("bench", help="every strategy over a camera path, against the truth")
    b.add_argument("scene", help="scene file or sample scene name (city, assembly, ...)")
    b.add_argument("--camera", help="camera path JSON (default: the sample scene's own path)")
    b.add_argument("--strategies", default=",".join(STRATEGIES))
    b.add_argument("--resolution", default=res)
    b.add_argument("--frames", type=int, help="use only this many frames, evenly spread")
    b.add_argument("--out", help="report folder (default reports/ with --plot or --snapshot)")
    b.add_argument("--plot", action="store_true", help="PNG plots along the path")
    b.add_argument("--snapshot", action="store_true", help="pictures of one frame")
    b.add_argument("--hierarchies", help="compare hierarchy builders instead of strategies: "
                   "comma list of tree, pHBVO, DBVS, octree, balanced, auto")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench)

    d = sub.add_parser("demo", help="generate the sample scene(s) and benchmark them")
    d.add_argument("--all", action="store_true", help="every sample scene, not only city")
    d.add_argument("--out", default="reports")
    d.add_argument("--resolution", default=res)
    d.add_argument("--frames", type=int)
    d.set_defaults(func=cmd_demo)
