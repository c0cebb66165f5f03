"""The report folder of ``bench --out`` and ``demo``: tables, JSON, plots and pictures."""

import json
import os
import time

import numpy as np

from .bench import format_table, run_bench
from .engine import DEFAULT_RESOLUTION, Culler
from .errors import OccError
from .jobs import load_job
from .strategies import STRATEGIES
from .traversal import Visibility


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


