"""The benchmark as a library: every strategy over a camera path in one process,
measured against the object-ID truth (``python -m core bench`` is its front-end in
:mod:`core.lab.cli`; the report folder is written by :mod:`core.lab.reports`).

Per strategy, over the whole path: median and p95 frame ms, culling overhead
(traversal + queries), triangles drawn and the render rate, queries issued and
skipped by the occupancy map, query rectangle pixels, false negatives and R/V'
(objects kept over objects truly visible).  Speed-ups are ratios within one run.
"""

import resource
import time
from dataclasses import dataclass, field, fields, replace

import numpy as np

from .. import STRATEGIES
from ..engine import DEFAULT_RESOLUTION, Culler
from ..errors import OccError

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


def _extra():
    """A field only some rows carry: None, and left out of :meth:`BenchRow.as_dict`, when unset."""
    return field(default=None, metadata={"extra": True})


@dataclass
class BenchRow:
    """One strategy's row of the benchmark (or one builder's of ``bench --hierarchies``):
    its figures over the camera path, per frame unless said otherwise.

    :func:`summarise` fills the first groups from the passes' rows; :func:`run_bench` adds
    the rounds, the memory and the per-frame series, the envelope's row what it hides,
    :func:`add_speedups` the ratios, :func:`run_hierarchies` the builder's figures.
    :meth:`as_dict` is the row of the ``--json`` report (docs/scripting.md, 'Report
    schema'): these keys, in this order, the extras only when set.
    """

    # time, ms
    frame_ms_median: float           # with rounds: the median of the rounds' medians
    frame_ms_p95: float
    culling_ms: float                # traversal + queries, mean
    traversal_ms: float
    query_ms: float
    draw_ms: float
    cpu_ms: float                    # outside GL calls, mean
    cpu_ms_median: float
    gl_ms: float
    gl_calls: float | None           # mean; None: a renderer that does not count them (null in the JSON)
    blocking_reads: float | None     # mean; as gl_calls
    # work, mean per frame
    triangles: float                 # triangles drawn
    render_rate: float               # % of the scene's triangles drawn
    queries: float
    queries_skipped: float           # boxes drawn or opened without a test
    multiple_queries: float
    query_pixels: float              # pixels the query boxes rasterise
    query_rect_pixels: float         # pixels of their screen rectangles
    nodes_visited: float
    fresh_passes: float              # share of passes that started without memory
    # the answer against the object-ID truth
    false_negatives: int             # objects culled although visible, summed over the path (must be 0)
    conservativity: float            # R/V': objects kept over objects truly visible
    objects_kept: float
    objects_truly_visible: float
    # run_bench's rows
    frame_ms_rounds: list[float] | None = _extra()           # each round's median frame
    peak_rss_mb: float | None = _extra()                     # of the process so far, MiB
    per_frame: dict[str, list] | None = _extra()             # {"frame_ms": [..], "triangles": [..]}, a round's
    # the envelope's row
    hidden_kept: float | None = _extra()                     # share of the default's hidden objects it hides
    hidden_triangles_kept: float | None = _extra()           # the same in triangles
    # speed-ups within one run (add_speedups)
    speedup_over_vfc: float | None = _extra()
    speedup_over_stopwait: float | None = _extra()
    # bench --hierarchies
    builder: str | None = _extra()                           # the builder chosen (auto's choice)
    inner_nodes: int | None = _extra()
    leaf_nodes: int | None = _extra()
    units: int | None = _extra()
    build_s: float | None = _extra()
    structure_mb: float | None = _extra()
    frustum_ms: float | None = _extra()                      # mean
    occlusion_ms: float | None = _extra()                    # traversal + queries - frustum, mean
    fps: float | None = _extra()                             # of the median frame

    def as_dict(self) -> dict:
        """The row as plain JSON values, unset extras left out."""
        return {f.name: v for f in fields(self)
                if (v := getattr(self, f.name)) is not None or not f.metadata.get("extra")}


def report_json(report: dict, per_frame: bool = True) -> dict:
    """The report of :func:`run_bench` or :func:`run_hierarchies` as plain JSON values
    (what ``--json`` prints and the report folder holds): its rows as dicts, without
    their per-frame series unless ``per_frame``."""
    out = dict(report)
    for key in ("strategies", "hierarchies"):
        if key in report:
            out[key] = {name: {k: v for k, v in row.as_dict().items() if per_frame or k != "per_frame"}
                        for name, row in report[key].items()}
    return out


def peak_rss_mb():
    """Peak resident memory of this process so far, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


ENVELOPE_VIEWS = 4        # views of the envelope sampled per frame for the envelope row's FN


def run_bench(scene, cameras, strategies, resolution=DEFAULT_RESOLUTION, warmup=1, culler_kw=None,
              progress=None, rounds=1, envelope=None, display=None):
    """Run every strategy over ``cameras``; returns the report dict, its ``strategies``
    :class:`BenchRow` s (:func:`report_json`: the ``--json`` shape).

    ``rounds``: the whole path this many times for each strategy, the strategies'
    order rotated each round (a new strategy each time: nothing learnt carries over),
    so that a machine busy with something else for a while slows every strategy
    alike; a strategy's median frame is then the median of its rounds' medians
    (``frame_ms_rounds``), its other figures those of all its passes.

    ``envelope``: a :class:`core.envelope.Envelope`; adds the row ``envelope D,A``
    (its pass, whatever the strategy) whose ``false_negatives`` count the frame's
    view and :data:`ENVELOPE_VIEWS` seeded views of the envelope per frame, and
    whose ``hidden_kept`` is the share of the default strategy's hidden objects it
    still hides (``hidden_triangles_kept`` the same in triangles).

    ``display``: ``(W, H)`` above the query resolution: queries at ``resolution``,
    conservative at the display's (``Culler(display=)``), and every false negative
    counted against the object-ID truth at the display's resolution."""
    unknown = [s for s in strategies if s not in STRATEGIES]
    if unknown:
        raise OccError(f"unknown strategies {unknown}; choose from {', '.join(STRATEGIES)}")
    if rounds < 1:
        raise OccError(f"rounds must be at least 1, not {rounds}")
    culler = Culler(scene, resolution, strategy=strategies[0], display=display, **(culler_kw or {}))
    # the truth at the display's resolution where one is given (on the same GL context)
    seer = culler if display is None else Culler(scene, display, strategy="vfc", ctx=culler.renderer.ctx)
    try:
        truths = [seer.truth(cam) for cam in cameras]
        tri_total = int(scene.triangle_counts.sum())
        report = {"objects": len(scene), "triangles_total": tri_total, "frames": len(cameras),
                  "resolution": list(resolution), "device": culler.renderer.device, "rounds": rounds,
                  "strategies": {}}
        if display is not None:
            report["display"] = list(display)
        runs: dict[str, list[list[dict]]] = {name: [] for name in strategies}
        rows_of = {}
        for k in range(rounds):
            shift = k % len(strategies)
            for name in strategies[shift:] + strategies[:shift]:
                runs[name].append(_path(culler, name, cameras, truths, warmup))
                if len(runs[name]) == rounds:
                    rows_of[name] = _summary(runs[name], tri_total)
                    if progress:
                        progress(name, rows_of[name])
        report["strategies"] = {name: rows_of[name] for name in strategies}
        if envelope is not None:
            name = f"envelope {envelope.distance:g},{envelope.angle_deg:g}"
            report["strategies"][name] = _envelope_row(culler, seer, cameras, truths, envelope, tri_total)
            if progress:
                progress(name, report["strategies"][name])
        add_speedups(report["strategies"])
        return report
    finally:
        if seer is not culler:
            seer.close()
        culler.close()


def _path(culler, name, cameras, truths, warmup):
    """One strategy, new, over the whole path: the rows of its passes."""
    culler.set_strategy(name)
    for cam, truth in zip(cameras[:warmup], truths, strict=False):   # compile, warm caches
        culler.cull(cam, truth=truth)
    culler.set_strategy(name)
    rows = []
    for cam, truth in zip(cameras, truths, strict=True):
        r = culler.cull(cam, truth=truth)
        fn = int((truth & ~r.visible).sum())
        rows.append({**r.stats.as_dict(), "false_negatives": fn, "truly_visible": int(truth.sum())})
    return rows


def _envelope_row(culler, seer, cameras, truths, envelope, tri_total):
    """The envelope's row: its pass per frame against the frame's truth and sampled
    views of the envelope (``seer``'s truth: the display's where one is given), and
    what it hides beside a point pass of the default."""
    from .. import DEFAULT_STRATEGY
    from ..envelope import sample_views
    rng = np.random.default_rng(0)
    tri = culler.scene.triangle_counts
    # as live mode asks it: the pass may keep the eyes above a floor (its result's envelope)
    envelope = replace(envelope, above_floor=True)
    culler.set_strategy(DEFAULT_STRATEGY)
    culler.cull(cameras[0], envelope=envelope)                       # warm-up
    rows, point_hidden, env_hidden, point_tri, env_tri = [], 0, 0, 0, 0
    for cam, truth in zip(cameras, truths, strict=True):
        point = culler.cull(cam)
        r = culler.cull(cam, envelope=envelope)
        seen = truth.copy()
        for view in sample_views(cam, r.envelope, ENVELOPE_VIEWS, rng):
            seen |= seer.truth(view)
        hidden = ~r.visible
        point_hidden += int((~point.visible).sum())
        env_hidden += int(hidden.sum())
        point_tri += int(tri[~point.visible].sum())
        env_tri += int(tri[hidden].sum())
        stats = {**r.stats.as_dict(), "triangles_drawn": r.stats.triangles_visible}   # what drawing it would draw
        rows.append({**stats, "false_negatives": int((seen & hidden).sum()), "truly_visible": int(truth.sum())})
    row = _summary([rows], tri_total)
    row.hidden_kept = env_hidden / max(point_hidden, 1)
    row.hidden_triangles_kept = env_tri / max(point_tri, 1)
    return row


def _summary(runs, tri_total) -> BenchRow:
    """A strategy's row from its rounds (lists of pass rows): the median of the rounds'
    median frames, every other figure over all passes; the per-frame series of the
    round with the median frame (the plots')."""
    row = summarise([x for rows in runs for x in rows], tri_total)
    medians = [float(np.median([x["total_ms"] for x in rows])) for rows in runs]
    row.frame_ms_median = float(np.median(medians))
    row.frame_ms_rounds = medians
    row.peak_rss_mb = round(peak_rss_mb(), 1)
    middle = runs[int(np.argsort(medians)[(len(medians) - 1) // 2])]
    row.per_frame = {"frame_ms": [round(x["total_ms"], 3) for x in middle],
                     "triangles": [x["triangles_drawn"] for x in middle]}
    return row


HIERARCHY_COLUMNS = (
    ("builder", "{:<16}"), ("inner", "{:>7d}"), ("leaves", "{:>7d}"), ("units", "{:>7d}"),
    ("build s", "{:>8.2f}"), ("mem MB", "{:>7.1f}"), ("frustum ms", "{:>10.2f}"), ("occlusion ms", "{:>12.2f}"),
    ("draw ms", "{:>8.2f}"), ("render %", "{:>8.2f}"), ("fps", "{:>7.1f}"), ("median ms", "{:>9.2f}"),
    ("FN", "{:>4d}"),
)


def run_hierarchies(scene, cameras, builders, resolution=DEFAULT_RESOLUTION, strategy=None,
                    chunk_triangles=None, progress=None):
    """The seed's Appendix A table: per builder, nodes, build time and per-frame times;
    the report dict, its ``hierarchies`` :class:`BenchRow` s (:func:`report_json`: the JSON)."""
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
                rows.append({**r.stats.as_dict(), "false_negatives": int((truth & ~r.visible).sum()),
                             "truly_visible": int(truth.sum())})
            h = culler.hierarchy
            s = summarise(rows, tri_total)
            s.builder, s.inner_nodes, s.leaf_nodes = chosen, int((~h.is_leaf).sum()), int(h.is_leaf.sum())
            s.units, s.build_s, s.structure_mb = len(culler.units), build_s, culler.structure_mb()
            s.frustum_ms = float(np.mean([x["frustum_ms"] for x in rows]))
            s.occlusion_ms = float(np.mean([x["traversal_ms"] + x["query_ms"] - x["frustum_ms"] for x in rows]))
            s.fps = 1e3 / max(s.frame_ms_median, 1e-9)
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
        label = name if s.builder == name else f"{name}:{s.builder}"
        vals = [label, s.inner_nodes, s.leaf_nodes, s.units, s.build_s, s.structure_mb, s.frustum_ms,
                s.occlusion_ms, s.draw_ms, s.render_rate, s.fps, s.frame_ms_median, s.false_negatives]
        lines.append(" ".join(fmt.format(v) for (_, fmt), v in zip(HIERARCHY_COLUMNS, vals, strict=True)))
    return "\n".join(lines)


def summarise(rows, tri_total) -> BenchRow:
    """Aggregate per-frame stats (the passes' rows: :meth:`PassStats.as_dict` with
    ``false_negatives`` and ``truly_visible``) into one row of the table."""
    ms = np.array([x["total_ms"] for x in rows])
    mean = {k: float(np.mean([x.get(k, 0) for x in rows])) for k in
            ("triangles_drawn", "queries", "queries_skipped", "query_rect_pixels", "query_raster_pixels",
             "traversal_ms", "query_ms", "draw_ms", "cpu_ms", "gl_ms", "visible", "truly_visible",
             "multiple_queries", "nodes_visited", "fresh")}
    counted = {k: (float(np.mean([x[k] for x in rows])) if all(x.get(k, -1) >= 0 for x in rows) else None)
               for k in ("gl_calls", "blocking_reads")}
    kept = sum(x["visible"] for x in rows)
    seen = sum(x["truly_visible"] for x in rows)
    return BenchRow(
        frame_ms_median=float(np.median(ms)),
        frame_ms_p95=float(np.percentile(ms, 95)),
        culling_ms=mean["traversal_ms"] + mean["query_ms"],
        traversal_ms=mean["traversal_ms"], query_ms=mean["query_ms"],
        draw_ms=mean["draw_ms"],
        cpu_ms=mean["cpu_ms"], cpu_ms_median=float(np.median([x.get("cpu_ms", 0.0) for x in rows])),
        gl_ms=mean["gl_ms"],
        gl_calls=counted["gl_calls"], blocking_reads=counted["blocking_reads"],
        triangles=mean["triangles_drawn"],
        render_rate=100.0 * mean["triangles_drawn"] / max(tri_total, 1),
        queries=mean["queries"], queries_skipped=mean["queries_skipped"],
        multiple_queries=mean["multiple_queries"],
        query_pixels=mean["query_raster_pixels"],
        query_rect_pixels=mean["query_rect_pixels"],
        nodes_visited=mean["nodes_visited"], fresh_passes=mean["fresh"],
        false_negatives=int(sum(x["false_negatives"] for x in rows)),
        conservativity=kept / max(seen, 1),
        objects_kept=mean["visible"], objects_truly_visible=mean["truly_visible"],
    )


def add_speedups(strategies: dict[str, BenchRow]) -> None:
    """Every row's speed-up over vfc and over stopwait, where they ran."""
    for base in ("vfc", "stopwait"):
        if base in strategies:
            ref = strategies[base].frame_ms_median
            for row in strategies.values():
                setattr(row, f"speedup_over_{base}", ref / max(row.frame_ms_median, 1e-9))


def format_table(report, title=""):
    head = " ".join(fmt.replace(".2f", "").replace(".0f", "").replace(".1f", "")
                    .replace("d}", "}").format(name) for name, fmt in TABLE_COLUMNS)
    lines = [title, f"{report['objects']} objects, {report['triangles_total']:,} triangles, "
             f"{report['frames']} frames at {report['resolution'][0]}x{report['resolution'][1]}"
             + (f", {report['rounds']} rounds (median of the rounds' medians)" if report.get("rounds", 1) > 1 else "")
             + f", device: {report['device']}", head, "-" * len(head)]
    for name, s in report["strategies"].items():
        nan = float("nan")
        vals = [name, s.frame_ms_median, s.frame_ms_p95, s.cpu_ms,
                nan if s.gl_calls is None else s.gl_calls,
                nan if s.blocking_reads is None else s.blocking_reads,
                s.triangles, s.render_rate, s.queries, s.queries_skipped, s.query_pixels,
                s.false_negatives, s.conservativity,
                nan if s.speedup_over_vfc is None else s.speedup_over_vfc,
                nan if s.speedup_over_stopwait is None else s.speedup_over_stopwait]
        lines.append(" ".join(fmt.format(v) for (_, fmt), v in zip(TABLE_COLUMNS, vals, strict=True)))
    return "\n".join(line for line in lines if line is not None)
