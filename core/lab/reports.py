"""The report folder of ``bench --out`` and ``demo``: tables, JSON, plots, pictures, an index.

Every picture carries a title, a legend and a caption that says what it shows; the
index ``README.txt`` lists every file of the folder with one line on what it holds.
Plots and pictures need matplotlib (a development dependency).
"""

import contextlib
import glob
import json
import os
import time

import numpy as np

from .. import STRATEGIES, Visibility
from ..cull import view_pass
from ..engine import DEFAULT_RESOLUTION, Culler
from ..errors import OccError
from ..occupancy import OccupancyMap
from .bench import format_table, report_json, run_bench
from .images import STATE_COLOURS, colour_by_state
from .jobs import load_job

# file name pattern (after the scene title) -> what the index says about it
FILES = (
    (".json", "the benchmark report: per strategy the summary and every frame's time and triangles "
              "(schema in docs/scripting.md, 'Report schema')"),
    (".txt", "the benchmark table as printed (columns explained in docs/performance.md, 'Reading the tables')"),
    ("_frame_ms.png", "frame time along the camera path per strategy, log scale"),
    ("_triangles.png", "triangles drawn along the camera path per strategy, log scale"),
    ("_view.png", "the middle frame as the camera sees it, one shade per visible object, with the counts of "
                  "visible, occluded and outside-the-view objects"),
    ("_occluded_xray.png", "the same frame: where the occluded objects lie (red) behind the visible view"),
    ("_occupancy.png", "the occupancy map of that frame's pass: when each tile was first covered, "
                       "front to back, while the map decided which queries to skip"),
    ("_tradeoff.json", "speed against accuracy per knob and preset, with the noise-aware Pareto front"),
    ("_tradeoff.png", "the speed/accuracy plot: median frame ms (with spread) against pixels missed"),
    ("_hierarchies.json", "hierarchy builders compared (bench --hierarchies)"),
    ("_hierarchies.txt", "the hierarchy table as printed"),
)


def pyplot():
    """matplotlib's pyplot on the file-only backend, or a clear error."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise OccError("plots and pictures need matplotlib: pip install matplotlib") from None
    return plt


def _caption(fig, text):
    fig.text(0.01, 0.01, text, fontsize=8, ha="left", va="bottom", wrap=True)


def write_plots(report, out_dir, title):
    """Frame time and triangles along the path per strategy (the papers' Figures 5-11), log scale:
    one strategy's spikes must not flatten the others into one line."""
    plt = pyplot()
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    for key, label in (("frame_ms", "frame time (ms)"), ("triangles", "triangles drawn")):
        fig, ax = plt.subplots(figsize=(9, 4.6))
        for name, s in report["strategies"].items():
            values = np.asarray(s.per_frame[key], dtype=np.float64)
            summary = (f"median {s.frame_ms_median:.1f} ms" if key == "frame_ms"
                       else f"mean {s.triangles:,.0f}")
            ax.plot(np.maximum(values, 1 if key == "triangles" else 1e-3), label=f"{name} ({summary})")
        ax.set_xlabel("frame of the camera path")
        ax.set_ylabel(label + ", log scale")
        ax.set_yscale("log")
        ax.set_title(f"{title}: {label} per strategy")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=8, ncol=2)
        _caption(fig, f"{report['objects']} objects, {report['triangles_total']:,} triangles, "
                      f"{report['frames']} frames at {report['resolution'][0]}x{report['resolution'][1]} on "
                      f"{report['device']}.  Lower is better.")
        fig.tight_layout(rect=(0, 0.05, 1, 1))
        path = os.path.join(out_dir, f"{title}_{key}.png")
        fig.savefig(path, dpi=90)
        plt.close(fig)
        paths.append(path)
    return paths


class _RecordingMap(OccupancyMap):
    """The occupancy map of one pass that remembers when each tile was first set and how
    often the map was asked; the engine's own map, only watched."""

    last = None

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.first_set = np.full(self.grid.shape, -1, dtype=np.int64)
        self.sets = self.asks = self.said_empty = 0
        self.asked = []                      # (tile rectangles (k, 4), answered empty (k,) bool)
        _RecordingMap.last = self

    def set_tiles(self, t):
        before = self.grid.copy()
        super().set_tiles(t)
        self.first_set[self.grid & ~before] = self.sets
        self.sets += 1

    def any_empty_tiles(self, t):
        empty = super().any_empty_tiles(t)
        self.asked.append((np.array(t, dtype=np.int64).reshape(-1, 4), np.array(empty, dtype=bool)))
        self.asks += len(empty)
        self.said_empty += int(np.sum(empty))
        return empty


@contextlib.contextmanager
def _watched_occupancy_map():
    """Passes started inside build their occupancy map as a :class:`_RecordingMap`."""
    original, _RecordingMap.last = view_pass.OccupancyMap, None
    view_pass.OccupancyMap = _RecordingMap
    try:
        yield
    finally:
        view_pass.OccupancyMap = original


def _legend_image(ax, image, labels, colours, title):
    from matplotlib.patches import Patch
    ax.imshow(image, interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title, fontsize=10)
    ax.legend(handles=[Patch(color=np.asarray(c) / 255.0, label=lab) for lab, c in zip(labels, colours,
                                                                                          strict=True)],
              loc="upper right", fontsize=7, framealpha=0.85)


def write_snapshot(scene, camera, out_dir, title, resolution, strategy="om_multi", frame_label=""):
    """One frame: the view coloured by state, the occluded objects x-rayed, the occupancy map
    as it filled during the pass; each picture with a legend and a caption."""
    plt = pyplot()
    os.makedirs(out_dir, exist_ok=True)
    with Culler(scene, resolution, strategy=strategy) as c:
        with _watched_occupancy_map():
            result = c.cull(camera)
        om = _RecordingMap.last
        ids = c.renderer.object_ids(camera)
        hidden = np.flatnonzero(result.state == Visibility.OCCLUDED)
        xray = c.renderer.object_ids(camera, hidden)
    s = result.stats
    where = f"{title}, {frame_label or 'one frame'}, strategy {strategy}, {resolution[0]}x{resolution[1]}"
    counts = (f"{s.visible} visible, {s.occluded} occluded, {s.view_culled} outside the view "
              f"of {s.objects} objects")
    view = colour_by_state(ids, result.state, shade=True)
    # x-ray: where occluded objects lie (red) over the visible view, dimmed
    xr = (view // 3).copy()
    xr[(xray >= 0)[::-1]] = STATE_COLOURS[Visibility.OCCLUDED]
    paths = {"view": os.path.join(out_dir, f"{title}_view.png"),
             "xray": os.path.join(out_dir, f"{title}_occluded_xray.png"),
             "occupancy": os.path.join(out_dir, f"{title}_occupancy.png")}
    aspect = resolution[0] / resolution[1]
    for key, image, labels, colours, head in (
            ("view", view, ("visible (a shade per object)", "background"),
             (STATE_COLOURS[Visibility.VISIBLE], STATE_COLOURS[-1]), "what the camera sees"),
            ("xray", xr, ("occluded objects, seen through what hides them",
                          "the visible view, dimmed (colours as in _view.png)"),
             (STATE_COLOURS[Visibility.OCCLUDED], (70, 70, 80)), "what culling hid")):
        fig, ax = plt.subplots(figsize=(7, 7 / aspect + 0.6))
        _legend_image(ax, image, labels, colours, f"{title}: {head}")
        _caption(fig, f"{where}: {counts}; the occluded ones are in _occluded_xray.png.")
        fig.tight_layout(rect=(0, 0.05, 1, 1))
        fig.savefig(paths[key], dpi=90)
        plt.close(fig)

    _occupancy_figure(plt, om, result, s, paths["occupancy"], title, where, aspect)
    return paths


def _occupancy_figure(plt, om, result, stats, path, title, where, aspect):
    """Left: when each tile was first covered.  Right: every question the map answered, as the
    tile rectangle asked about, green where it said 'still empty' (the box was drawn or opened
    without a query) and red where it said 'covered' (a query had to decide)."""
    from matplotlib.patches import Patch, Rectangle
    if om is None or not om.sets:            # the strategy never drew through the map (vfc, oracle)
        fig, ax = plt.subplots(figsize=(7, 7 / aspect + 0.9))
        ax.imshow(np.where(result.occupancy[::-1], 1.0, 0.15), cmap="gray", vmin=0, vmax=1,
                  interpolation="nearest")
        ax.set_axis_off()
        ax.set_title(f"{title}: occupancy map at the end of the pass", fontsize=10)
        _caption(fig, f"{where}: this strategy does not consult the occupancy map; white: covered.")
        fig.tight_layout(rect=(0, 0.07, 1, 1))
        fig.savefig(path, dpi=90)
        plt.close(fig)
        return
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 6.5 / aspect + 1.2))
    order = np.ma.masked_less(om.first_set[::-1], 0)
    im = left.imshow(order, cmap="viridis", interpolation="nearest", vmin=0, vmax=max(om.sets - 1, 1))
    left.set_facecolor((0.1, 0.1, 0.12))
    bar = fig.colorbar(im, ax=left, fraction=0.04, pad=0.02)
    bar.set_label("draw batch that first covered the tile", fontsize=8)
    left.set_title("when each tile was first covered (front to back)", fontsize=10)
    right.imshow(np.zeros((om.rows, om.cols)), cmap="gray", vmin=0, vmax=1)
    for rects, empty in om.asked:
        for (x0, y0, x1, y1), e in zip(rects.tolist(), empty.tolist(), strict=True):
            right.add_patch(Rectangle((x0 - 0.5, om.rows - 1 - y1 - 0.5), x1 - x0 + 1, y1 - y0 + 1, fill=False,
                                      lw=0.6, alpha=0.7, edgecolor=(0.3, 0.9, 0.4) if e else (0.95, 0.3, 0.25)))
    right.legend(handles=[Patch(color=(0.3, 0.9, 0.4), label="'still empty': no query needed"),
                          Patch(color=(0.95, 0.3, 0.25), label="'covered': a query decided")],
                 loc="upper right", fontsize=7, framealpha=0.85)
    right.set_title("what the map was asked, and its answer", fontsize=10)
    for ax in (left, right):
        ax.set_xlim(-0.5, om.cols - 0.5)
        ax.set_ylim(om.rows - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
    filled = 100.0 * float(np.mean(om.first_set >= 0))
    first = 100.0 * float(np.mean(om.first_set == 0))
    fig.suptitle(f"{title}: the occupancy map during the pass", fontsize=11)
    _caption(fig, f"{where}: {om.cols}x{om.rows} tiles, {om.sets} draw batches; the first covered {first:.0f}%, "
                  f"{filled:.0f}% at the end (dark: never covered); asked about {om.asks} boxes, "
                  f"{om.said_empty} 'still empty'; {stats.queries} queries issued.  A drawn box's screen "
                  "rectangle covers its tiles.")
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_index(out_dir):
    """``README.txt``: every file of the report folder with what it holds, then its tables."""
    lines = ["Report folder of the occlusion-culled viewport (python -m core demo / bench --out).",
             "Every file, with what it holds:", ""]
    for path in sorted(glob.glob(os.path.join(out_dir, "*"))):
        name = os.path.basename(path)
        if name == "README.txt":
            continue
        what = next((text for suffix, text in sorted(FILES, key=lambda f: -len(f[0])) if name.endswith(suffix)),
                    "not written by this tool")
        lines.append(f"  {name:<34} {what}")
    lines += ["", "Columns of the tables: median and p95 frame ms; cull ms = traversal + queries; triangles "
              "drawn per frame and render % of the scene; queries issued, skipped by the occupancy map, "
              "query rectangle pixels; FN = objects culled although visible (must be 0); R/V' = objects "
              "kept over objects truly visible; x vfc / x stopwait = speed-up over those strategies.", ""]
    for path in sorted(glob.glob(os.path.join(out_dir, "*.txt"))):
        if os.path.basename(path) != "README.txt":
            with open(path, encoding="utf-8") as f:
                lines += [f.read().rstrip(), ""]
    path = os.path.join(out_dir, "README.txt")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    return path


def bench_steps(strategies, plot=False, snapshot=False):
    """Steps of :func:`bench_scene` for a progress bar: loading, each strategy, plots, pictures."""
    return 1 + len(strategies) + bool(plot) + bool(snapshot)


def bench_scene(spec, camera=None, strategies=STRATEGIES, resolution=DEFAULT_RESOLUTION,
                frames=None, out_dir=None, plot=False, snapshot=False, progress=None, rounds=1, envelope=None,
                display=None):
    """Load a scene (file or sample name), run the benchmark, optionally write a report folder.

    ``progress``: a :class:`core.lab.jobs.Progress` that takes :func:`bench_steps` steps (None: silent).
    """
    step = progress.step if progress is not None else (lambda *a, **k: None)
    t = time.perf_counter()
    scene, cameras, title = load_job(spec, camera, frames)
    step(f"{title}: loaded {len(scene)} objects, {int(scene.triangle_counts.sum()):,} triangles "
         f"in {time.perf_counter() - t:.1f} s; {len(cameras)} frames")
    report = run_bench(scene, cameras, list(strategies), resolution, rounds=rounds, envelope=envelope, display=display,
                       progress=lambda n, s: step(f"{title} {n:<11} median {s.frame_ms_median:.2f} ms"))
    report["scene"] = title
    table = format_table(report, f"== {title} ==")
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        with open(os.path.join(out_dir, f"{title}.json"), "w") as f:
            json.dump(report_json(report), f, indent=1)
        with open(os.path.join(out_dir, f"{title}.txt"), "w") as f:
            f.write(table + "\n")
        if plot:
            write_plots(report, out_dir, title)
            step(f"{title} plots", line=False)
        if snapshot:
            k = len(cameras) // 2
            write_snapshot(scene, cameras[k], out_dir, title, resolution,
                           frame_label=f"frame {k} of {len(cameras)}")
            step(f"{title} pictures", line=False)
    return report, table
