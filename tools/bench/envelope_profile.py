"""Where an envelope pass's time goes, stage by stage, on this machine's GL:

    .venv/bin/python tools/bench/envelope_profile.py [SCENE] [--frames N] [--envelope D,A|rest]
        [--resolution WxH]

Culls SCENE's path (default ``city``, 640x360) with ``--envelope`` (default ``2,10``;
``rest``: live mode's envelope at rest, :meth:`core.motion.LivePolicy.rest`) the
way ``bench --envelope`` does (the first frame fresh, then the culler's memory of the
occluders), and times the stages of ``core.envelope``'s pass by wrapping them: the depth
image (the draw), the extended depth (GPU compute passes or numpy, with its read-back),
the pyramid, the boxes' classification, the occluder polygons and their proof.  The GL is
waited for after the draw (``ctx.finish()``) so the draw's own time shows; compare stages,
not totals, with ``bench``.  Prints a table of per-pass medians in ms.
"""

import argparse
import collections
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

from core import Culler  # noqa: E402
from core import envelope as E
from core.lab.jobs import load_job  # noqa: E402
from core.motion import LivePolicy  # noqa: E402

STAGES = {  # label: (module object, attribute)
    "depth image (draw)": None,
    "extended depth": (E, "extended_depth"),
    "pyramid": (E, "_pyramid"),
    "classify boxes": (E, "classify_boxes"),
    "occluder polygons": (E, "occluder_polygons"),
    "polygon proof": (E, "hidden_by_polygons"),
}


def wrap(times, label, owner, name):
    fn = getattr(owner, name)

    def timed(*a, **k):
        t = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            times[label] += time.perf_counter() - t
    setattr(owner, name, timed)
    return fn


def finish_wrap(times, label, cls, name, ctx):
    """Time ``cls.name`` with the GL waited for before and after (its own GPU time)."""
    fn = getattr(cls, name)

    def timed(self, *a, **k):
        ctx.finish()
        t = time.perf_counter()
        try:
            return fn(self, *a, **k)
        finally:
            ctx.finish()
            times[label] += time.perf_counter() - t
    setattr(cls, name, timed)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="city")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--envelope", default="2,10")
    ap.add_argument("--resolution", default="640x360")
    args = ap.parse_args(argv)
    scene, cameras, _ = load_job(args.scene, None, args.frames)
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    rows = collections.defaultdict(list)
    with Culler(scene, resolution=resolution) as c:
        env = LivePolicy().rest(c.scene_size) if args.envelope == "rest" else E.Envelope.parse(args.envelope)
        renderer = c.renderer
        device = renderer.device
        gpu = renderer.gpu_envelope()
        times = collections.Counter()
        for label, target in STAGES.items():
            if target:
                wrap(times, label, *target)
        if gpu is not None:
            wrap(times, "extended depth", gpu, "extended_depth")
            # inside it, the compute dispatches and the one read-back, each waited for
            import moderngl
            for label, cls, name in (("  of which dispatches", moderngl.ComputeShader, "run"),
                                     ("  of which read-back", moderngl.Buffer, "read")):
                STAGES[label] = None
                finish_wrap(times, label, cls, name, renderer.ctx)
        draw = renderer.envelope_depth

        def timed_draw(*a, **k):
            t = time.perf_counter()
            tex = draw(*a, **k)
            renderer.ctx.finish()
            times["depth image (draw)"] += time.perf_counter() - t
            return tex
        renderer.envelope_depth = timed_draw
        for i, cam in enumerate(cameras):
            times.clear()
            t = time.perf_counter()
            c.cull(cam, envelope=env, fresh=(i == 0))
            total = time.perf_counter() - t
            for label in STAGES:
                rows[label].append(1e3 * times[label])
            rows["whole pass"].append(1e3 * total)
    print(f"{args.scene}, --envelope {args.envelope} ({env.distance:.3g}, {env.angle_deg:g}), {len(cameras)} passes, "
          f"{args.resolution}, "
          f"{device}; image work: {'GPU compute' if gpu is not None else 'numpy'}")
    print("| stage | median ms | max ms |")
    print("|---|---|---|")
    for label, v in rows.items():
        print(f"| {label} | {np.median(v):.1f} | {max(v):.1f} |")
    other = np.array(rows["whole pass"]) - sum(np.array(rows[k]) for k in STAGES if not k.startswith(" "))
    print(f"| the rest (frustum, grown boxes, states) | {np.median(other):.1f} | {other.max():.1f} |")


if __name__ == "__main__":
    main()
