"""The engine's pass of a Cull click, outside Blender: ``tools/bench/blender_scale.py``'s rows of
cubes behind a wall, culled as the add-on's engine culls them.

    .venv/bin/python tools/bench/click_pass.py [--objects 50000] [--passes 20] [--steady]
                                         [--envelope] [--query-pixels] [--profile TOP]

A click restarts the strategy (``cull(fresh=True)``: a new engine's first pass, the
same click the same answer); ``--steady`` times the passes live mode makes after a
small view change instead (the strategy's memory kept).  The camera turns to and fro
by 0.01 rad between passes, at 1280x720 (the scale tool's render size and lens).
``--envelope``: the pass of a click from a 3D view (or with Live on), which hides only what
stays hidden for live mode's envelope at rest (its image drawn: the add-on's click probes).
Prints the median wall time of a pass, its process CPU time (llvmpipe's threads
included) and the pass's CPU time outside GL (``PassStats.cpu_ms``).  The add-on's
engine counts no query pixels (``Culler(query_pixels=False)``); ``--query-pixels``
counts them, as the bench does (and as the engine did for everyone before).
Run from another checkout's ``tools/`` to time its engine.
"""

import argparse
import cProfile
import inspect
import math
import os
import pstats
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)

import core  # noqa: E402
from core.camera import Camera  # noqa: E402

SIZE = (1280, 720)
FOV_X = 2.0 * math.atan(18.0 / 50.0)            # Blender's default camera: 36 mm sensor, 50 mm lens
CUBE_V = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
CUBE_F = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                   [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])


def rows(n):
    """The scale tool's ``build_rows``: ``n`` unit cubes in rows behind a long wall, as a
    ``core.Scene`` (one shared mesh), and the camera's eye and far distance."""
    cols = int(np.ceil(np.sqrt(2 * n)))
    width = 3.0 * cols
    i = np.arange(n)
    m = np.repeat(np.eye(4)[None], n + 1, axis=0)
    m[:n, 0, 3], m[:n, 1, 3], m[:n, 2, 3] = 2.0 + 3.0 * (i // cols), -width / 2 + 3.0 * (i % cols), 0.5
    lo, hi = np.array([0.0, -0.1 * width, -1.0]), np.array([0.5, 0.1 * width, 4.0])
    m[n, :3, :3] = np.diag(hi - lo)
    m[n, :3, 3] = (lo + hi) / 2
    names = [f"cube{k:06d}" for k in range(n)] + ["wall"]
    scene = core.Scene.from_arrays(names, [(CUBE_V, CUBE_F)], np.zeros(n + 1, dtype=np.int64), m)
    return scene, np.array([-0.6 * width, 0.0, 3.0]), 10.0 * width


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=50_000)
    ap.add_argument("--passes", type=int, default=20)
    ap.add_argument("--steady", action="store_true", help="live mode's passes: the strategy's memory kept")
    ap.add_argument("--envelope", action="store_true", help="live mode's envelope at rest (a click from a 3D view)")
    ap.add_argument("--query-pixels", action="store_true", help="count the query boxes' pixels (the bench's)")
    ap.add_argument("--profile", type=int, metavar="TOP", help="print the TOP entries of a cProfile of the passes")
    args = ap.parse_args()
    scene, eye, far = rows(args.objects)
    fov_y = math.degrees(2.0 * math.atan(math.tan(FOV_X / 2.0) * SIZE[1] / SIZE[0]))

    def camera(a):
        return Camera.look_at(eye, eye + [math.cos(a), math.sin(a), 0.0], [0, 0, 1], fov_y_deg=fov_y,
                              aspect=SIZE[0] / SIZE[1], near=0.1, far=far)

    kw = {}
    if "query_pixels" in inspect.signature(core.Culler).parameters:     # older engines count always
        kw["query_pixels"] = args.query_pixels
    t = time.perf_counter()
    culler = core.Culler(scene, SIZE, **kw)
    pass_kw = {}
    if args.envelope:
        from core.motion import LivePolicy
        pass_kw = {"envelope": LivePolicy().rest(culler.scene_size), "probe": True}
    first = culler.cull(camera(0.0), fresh=True, **pass_kw)
    print(f"{args.objects:,} cubes and a wall: built and culled in {time.perf_counter() - t:.2f} s, "
          f"{first.stats.occluded:,} occluded ({ROOT})")
    prof = cProfile.Profile() if args.profile else None
    wall, cpu, outside = [], [], []
    for k in range(args.passes):
        cam = camera(0.01 * (k % 2 == 0))
        t, c = time.perf_counter(), time.process_time()
        if prof:
            prof.enable()
        r = culler.cull(cam, fresh=not args.steady, **pass_kw)
        if prof:
            prof.disable()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        outside.append(r.stats.cpu_ms)
    kind = ("steady pass" if args.steady else "click's pass") + (", envelope at rest" if args.envelope else "")
    print(f"{kind}, median of {args.passes}: {1e3 * np.median(wall):.1f} ms, process CPU "
          f"{1e3 * np.median(cpu):.1f} ms, CPU outside GL {np.median(outside):.1f} ms "
          f"({r.stats.queries:,} queries, {r.stats.occluded:,} occluded)")
    culler.close()
    if prof:
        pstats.Stats(prof).sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()
