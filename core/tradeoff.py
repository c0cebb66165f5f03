"""Speed against accuracy (``python -m core tradeoff``), one knob at a time.

Culling runs at its query resolution; misses are counted against the object-ID
truth at the *display* resolution: objects missed (visible on the display but
culled), pixels missed (display pixels whose front-most object was culled) and
R/V'.  Each knob is swept from the default (conservative) settings; the Pareto
front of frame time against pixels missed is plotted per scene.
"""

import numpy as np

from .engine import Culler
from .errors import OccError
from .settings import PRESETS, CullOptions, query_resolution

# knob -> list of (label, options changes, culler keyword changes)
KNOBS = {
    "query_resolution": [(f"1/{d}", {"resolution_scale": 1.0 / d}, {}) for d in (1, 2, 3, 4)],
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


def measure(scene, cameras, truth_pixels, display, options, culler_kw, strategy="om_multi"):
    """One setting over the path: frame ms and misses at display resolution."""
    res = query_resolution(display, options)
    ms, obj_missed, px_missed, kept, seen = [], 0, 0, 0, 0
    with Culler(scene, res, strategy=strategy, options=options, **culler_kw) as c:
        c.cull(cameras[0])                                    # warm-up
        for cam, pixels in zip(cameras, truth_pixels, strict=True):
            r = c.cull(cam)
            ms.append(r.stats["total_ms"])
            culled = ~r.visible
            obj_missed += int((culled & (pixels > 0)).sum())
            px_missed += int(pixels[culled].sum())
            kept += int(r.visible.sum())
            seen += int((pixels > 0).sum())
    return {"query_resolution": list(res), "frame_ms_median": float(np.median(ms)),
            "objects_missed": obj_missed, "pixels_missed": px_missed,
            "pixels_missed_per_frame": px_missed / len(cameras),
            "conservativity": kept / max(seen, 1)}


def pareto(points):
    """Indices of points not dominated in (frame ms, pixels missed), both lower-better."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    dominated = np.any(np.all(p[None] <= p[:, None], axis=2) & np.any(p[None] < p[:, None], axis=2),
                       axis=1)
    return np.flatnonzero(~dominated)


def run_tradeoff(scene, cameras, display, knobs=tuple(KNOBS), log=print):
    truth = display_truth(scene, cameras, display)
    report = {"display": list(display), "frames": len(cameras), "knobs": {}, "presets": {}}
    for name in PRESETS:
        report["presets"][name] = measure(scene, cameras, truth, display, PRESETS[name], {})
        log(f"  preset {name:<12} {_fmt(report['presets'][name])}")
    for knob in knobs:
        if knob not in KNOBS:
            raise OccError(f"unknown knob '{knob}'; choose from {', '.join(KNOBS)}")
        rows = {}
        for label, changes, kw in KNOBS[knob]:
            rows[label] = measure(scene, cameras, truth, display, CullOptions(**changes), kw)
            log(f"  {knob:<22} {label:<9} {_fmt(rows[label])}")
        report["knobs"][knob] = rows
    points, labels = [], []
    for knob, rows in report["knobs"].items():
        for label, r in rows.items():
            points.append((r["frame_ms_median"], r["pixels_missed_per_frame"]))
            labels.append(f"{knob}={label}")
    report["pareto"] = [labels[i] for i in pareto(points)]
    return report


def _fmt(r):
    return (f"{r['frame_ms_median']:8.2f} ms  missed {r['objects_missed']:5d} objects "
            f"{r['pixels_missed_per_frame']:9.1f} px/frame  R/V' {r['conservativity']:.2f}")


def plot_tradeoff(report, path, title):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise OccError("--plot needs matplotlib: pip install matplotlib") from None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    pts = []
    for knob, rows in report["knobs"].items():
        xs = [r["frame_ms_median"] for r in rows.values()]
        ys = [r["pixels_missed_per_frame"] for r in rows.values()]
        ax.plot(xs, ys, "o-", label=knob, alpha=0.7)
        pts += [(x, y, f"{knob}={lab}") for x, y, lab in zip(xs, ys, rows, strict=True)]
    front = sorted((x, y) for x, y, lab in pts if lab in report["pareto"])
    if front:
        ax.plot(*zip(*front, strict=True), "k--", lw=1, label="Pareto front")
    for name, r in report["presets"].items():
        ax.plot(r["frame_ms_median"], r["pixels_missed_per_frame"], "k*", ms=12)
        ax.annotate(name, (r["frame_ms_median"], r["pixels_missed_per_frame"]))
    ax.set_xlabel("median frame ms (query resolution)")
    ax.set_ylabel(f"display pixels missed per frame ({report['display'][0]}x{report['display'][1]})")
    ax.set_yscale("symlog")
    ax.set_title(f"{title}: speed vs accuracy")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
