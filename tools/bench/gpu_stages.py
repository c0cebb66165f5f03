"""Time each stage of the ``gpu`` strategy's pass (core/gl/gpucull.py) on this machine:

    .venv/bin/python tools/bench/gpu_stages.py city [--empty]

Runs the sample scene's path (or, with ``--empty``, 40 passes from its first eye
looking straight up, where nothing is in the frustum) and waits for the GL after
every stage (``ctx.finish()``), so each stage's own time shows: the parameter write,
the five compute dispatches, the two multi-draws, the pyramid, the two box tests
and the read.  The waits add a little to the total: compare stages, not totals,
with ``bench``.  ``--empty`` also times ``vfc`` from the same view (the fixed cost
of a pass that tests nothing).
"""

import argparse
import collections
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

from core import Camera, Culler, load_scene  # noqa: E402
from core.gl import gpucull as G  # noqa: E402
from core.lab.jobs import resolve_cameras, resolve_scene  # noqa: E402


def timed_run(times):
    """``GpuCull.run`` waiting for the GL and reading the clock after every stage
    (its ``stage`` hook: the same GL work)."""
    run = G.GpuCull.run

    def timed(self, frame, pixels):
        self.ctx.finish()
        last = [time.perf_counter()]

        def stage(label):
            self.ctx.finish()
            now = time.perf_counter()
            times[label].append(1e3 * (now - last[0]))
            last[0] = now
        return run(self, frame, pixels, stage)
    return timed


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="a sample scene name")
    ap.add_argument("--empty", action="store_true", help="passes from a view with nothing in it, and vfc's")
    ap.add_argument("--resolution", default="640x360")
    args = ap.parse_args(argv)
    path, sample = resolve_scene(args.scene)
    scene = load_scene(path)
    cams = resolve_cameras(None, sample)
    res = tuple(int(v) for v in args.resolution.split("x"))
    if args.empty:
        eye = cams[0].eye
        cams = [Camera.look_at(eye, eye + np.array([1e-3, 0.0, 1.0]), up=(0, 1, 0), fov_y_deg=10,
                               aspect=res[0] / res[1], near=0.1, far=1e3)] * 40
    times = collections.defaultdict(list)
    G.GpuCull.run = timed_run(times)
    totals = {}
    for name in ("gpu", "vfc") if args.empty else ("gpu",):
        with Culler(scene, res, strategy=name) as c:
            totals[name] = [c.cull(cam).stats.total_ms for cam in cams][2:]      # after the first pass
    print(f"{args.scene}{' (empty view)' if args.empty else ''}, {len(cams)} passes at {args.resolution}: "
          + ", ".join(f"{k} median {np.median(v):.2f} ms" for k, v in totals.items()))
    for label, v in times.items():
        print(f"  {label:<26} median {np.median(v):6.3f} ms   mean {np.mean(v):6.3f} ms")


if __name__ == "__main__":
    main()
