"""Speed against accuracy (``python -m core tradeoff``), one knob at a time.

Culling runs at its query resolution; misses are counted against the object-ID
truth at the *display* resolution: objects missed (visible on the display but
culled), pixels missed (display pixels whose front-most object was culled) and
R/V'.  Each knob is swept from the default (conservative) settings; the Pareto
front of frame time against pixels missed is plotted per scene.

Timing is noisy, so every setting runs the path ``repeats`` times: its time is the
median of the repeats' medians and its spread half their range.  On the front, one
setting beats another on time only when their spreads do not overlap; misses are
exact.  The presets are candidates of the front like every knob setting.
"""

import numpy as np

from ..engine import Culler
from ..errors import OccError
from ..settings import PRESETS, CullOptions, query_resolution

# knob -> list of (label, options changes, culler keyword changes)
KNOBS = {
    "query_resolution": [(f"1/{d}", {"resolution_scale": 1.0 / d}, {}) for d in (1, 2, 3, 4)],
    # occluder depth drawn at the display's resolution, each query pixel keeping the
    # farthest depth it stands for: what the add-on's fast preset runs (exact by construction)
    "query_resolution+display": [(f"1/{d}+display", {"resolution_scale": 1.0 / d, "pixel_guard": 1.0},
                                  {"display_depth": True}) for d in (2, 3, 4)],
    "query_resolution+guard": [(f"1/{d}+1px", {"resolution_scale": 1.0 / d, "pixel_guard": 1.0}, {})
                               for d in (2, 3, 4)],
    "tiles": [(str(t), {"tiles": t}, {}) for t in (1024, 4096, 16384, 65536)],
    "visible_threshold": [(str(t), {"visible_threshold": t}, {}) for t in (0, 1, 4, 16, 64)],
    "bounds": [("mesh-box", {}, {"exact_bounds": False}), ("exact", {}, {"exact_bounds": True})],
    "max_children": [(str(k), {}, {"max_children": k}) for k in (2, 4, 8, 16)],
}


def display_truth(scene, cameras, display):
    """Per frame: the display-resolution ID buffer's per-object pixel counts, ``(n,) int64``."""
    out = []
    with Culler(scene, display, strategy="vfc") as c:
        for cam in cameras:
            ids = c.renderer.object_ids(cam)
            out.append(np.bincount(ids[ids >= 0], minlength=len(scene)))
    return out


def measure(scene, cameras, truth_pixels, display, options, culler_kw, strategy="om_multi", repeats=1):
    """One setting over the path, ``repeats`` times: frame ms (median of the repeats' medians,
    spread = half their range) and misses at display resolution (from the first repeat)."""
    res = query_resolution(display, options)
    culler_kw = dict(culler_kw)
    if culler_kw.pop("display_depth", False) and tuple(res) != tuple(display):
        culler_kw["display"] = tuple(display)
    medians, obj_missed, px_missed, kept, seen = [], 0, 0, 0, 0
    with Culler(scene, res, strategy=strategy, options=options, **culler_kw) as c:
        c.cull(cameras[0])                                    # warm-up
        for rep in range(repeats):
            ms = []
            for cam, pixels in zip(cameras, truth_pixels, strict=True):
                r = c.cull(cam)
                ms.append(r.stats.total_ms)
                if rep == 0:
                    culled = ~r.visible
                    obj_missed += int((culled & (pixels > 0)).sum())
                    px_missed += int(pixels[culled].sum())
                    kept += int(r.visible.sum())
                    seen += int((pixels > 0).sum())
            medians.append(float(np.median(ms)))
    return {"query_resolution": list(res), "frame_ms_median": float(np.median(medians)),
            "frame_ms_spread": float(np.ptp(medians)) / 2.0, "frame_ms_repeats": medians,
            "objects_missed": obj_missed, "pixels_missed": px_missed,
            "pixels_missed_per_frame": px_missed / len(cameras),
            "conservativity": kept / max(seen, 1)}


def pareto(points, spread=None):
    """Indices of points not dominated in (frame ms, pixels missed), both lower-better.

    ``spread``: per point, the half-width of its frame-time noise.  A point is faster than
    another only when their intervals do not overlap; overlapping times count as a tie
    (no spread: plain comparison).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    s = np.zeros(len(p)) if spread is None else np.asarray(spread, dtype=np.float64).reshape(-1)
    lo, hi = p[:, 0] - s, p[:, 0] + s
    # [i, j]: j against i
    time_better = hi[None, :] < lo[:, None]
    time_tie = (lo[None, :] <= hi[:, None]) & (lo[:, None] <= hi[None, :])
    time_no_worse = time_better | time_tie
    px_no_worse = p[None, :, 1] <= p[:, None, 1]
    px_better = p[None, :, 1] < p[:, None, 1]
    dominated = np.any(time_no_worse & px_no_worse & (time_better | px_better), axis=1)
    return np.flatnonzero(~dominated)


def tradeoff_steps(knobs=tuple(KNOBS)):
    """Steps of :func:`run_tradeoff` for a progress bar: the display truth, each preset and setting."""
    return 1 + len(PRESETS) + sum(len(KNOBS[k]) for k in knobs)


def run_tradeoff(scene, cameras, display, knobs=tuple(KNOBS), log=print, repeats=3, progress=None):
    """Presets and knob settings over the path, each ``repeats`` times; the report dict with
    the noise-aware Pareto front of presets and settings (labels ``preset=<name>``, ``knob=value``).

    ``log``: one line per setting with its figures; ``progress(label, result)``: after each of the
    :func:`tradeoff_steps` steps (``result`` None for the display truth)."""
    unknown = [k for k in knobs if k not in KNOBS]
    if unknown:
        raise OccError(f"unknown knobs {', '.join(unknown)}; choose from {', '.join(KNOBS)}")
    progress = progress or (lambda label, result: None)
    truth = display_truth(scene, cameras, display)
    progress("display truth", None)
    report = {"display": list(display), "frames": len(cameras), "repeats": repeats, "knobs": {},
              "presets": {}}
    for name in PRESETS:
        # presets as the add-on runs them: occluder depth at the display's resolution
        report["presets"][name] = measure(scene, cameras, truth, display, PRESETS[name], {"display_depth": True},
                                          repeats=repeats)
        log(f"  preset {name:<12} {_fmt(report['presets'][name])}")
        progress(f"preset={name}", report["presets"][name])
    for knob in knobs:
        rows = {}
        for label, changes, kw in KNOBS[knob]:
            rows[label] = measure(scene, cameras, truth, display, CullOptions(**changes), kw, repeats=repeats)
            log(f"  {knob:<22} {label:<9} {_fmt(rows[label])}")
            progress(f"{knob}={label}", rows[label])
        report["knobs"][knob] = rows
    candidates = [(f"preset={n}", r) for n, r in report["presets"].items()]
    candidates += [(f"{knob}={label}", r) for knob, rows in report["knobs"].items() for label, r in rows.items()]
    front = pareto([(r["frame_ms_median"], r["pixels_missed_per_frame"]) for _, r in candidates],
                   [r["frame_ms_spread"] for _, r in candidates])
    report["pareto"] = [candidates[i][0] for i in front]
    return report


def _fmt(r):
    return (f"{r['frame_ms_median']:8.2f} ms (+-{r['frame_ms_spread']:.2f})  missed {r['objects_missed']:5d} "
            f"objects {r['pixels_missed_per_frame']:9.1f} px/frame  R/V' {r['conservativity']:.2f}")


def plot_tradeoff(report, path, title):
    """Median frame ms with its spread against display pixels missed, per knob and preset, and the
    front; the y axis starts at 0 (symlog above 1 pixel).  Returns the y limits."""
    from .reports import pyplot
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 5.2))
    for knob, rows in report["knobs"].items():
        xs = [r["frame_ms_median"] for r in rows.values()]
        ys = [r["pixels_missed_per_frame"] for r in rows.values()]
        ax.errorbar(xs, ys, xerr=[r["frame_ms_spread"] for r in rows.values()], fmt="o-", ms=4,
                    capsize=2, label=knob, alpha=0.75)
    every = {f"preset={n}": r for n, r in report["presets"].items()}
    every.update({f"{k}={lab}": r for k, rows in report["knobs"].items() for lab, r in rows.items()})
    front = sorted((every[lab]["frame_ms_median"], every[lab]["pixels_missed_per_frame"])
                   for lab in report["pareto"])
    if front:
        ax.plot(*zip(*front, strict=True), "k--", lw=1, label="Pareto front (noise-aware)")
    for name, r in report["presets"].items():
        ax.errorbar(r["frame_ms_median"], r["pixels_missed_per_frame"], xerr=r["frame_ms_spread"], fmt="k*",
                    ms=12, capsize=2)
        ax.annotate(f"preset {name}", (r["frame_ms_median"], r["pixels_missed_per_frame"]),
                    textcoords="offset points", xytext=(6, 6), fontsize=8)
    ax.set_xlabel(f"median frame ms at the query resolution (bars: spread over {report.get('repeats', 1)} runs)")
    ax.set_ylabel(f"display pixels missed per frame ({report['display'][0]}x{report['display'][1]})")
    top = max([r["pixels_missed_per_frame"] for r in every.values()] + [0.0])
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_ylim(0.0, max(1.0, top) * 1.5)           # nothing below 0 pixels: no negative axis
    ax.set_title(f"{title}: speed against accuracy")
    ax.grid(True, alpha=0.25)
    ax.legend(fontsize=7)
    fig.text(0.01, 0.01, f"{report['frames']} frames; lower left is better; a setting is on the front when no "
             "other is measurably faster (spreads apart) and misses no more.", fontsize=8)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    fig.savefig(path, dpi=90)
    limits = ax.get_ylim()
    plt.close(fig)
    return limits
