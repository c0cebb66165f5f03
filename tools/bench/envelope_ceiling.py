"""How much of what a point pass hides an envelope pass could hide at most: the
sampled ceiling.

For each frame of a sample scene's path: the point pass (the default strategy), the
envelope pass, and the object-ID truth from the frame's view and from VIEWS seeded views of
the envelope (``core.envelope.sample_views``: eyes in the ball, directions in the cone).
An object no sampled view sees is in the ceiling: every sound envelope pass hides at most
those (sampling misses a view that sees one, so the ceiling is high, never low).  The
envelope is live mode's (its eyes kept off the nearest face, where the pass finds one: the
views are sampled from the envelope the pass used); ``--ball`` keeps every eye of the ball.
Printed per frame and summed: the point pass's hidden objects, the envelope's, the ceiling, the
envelope's share of the ceiling and the false negatives against the sampled views (0 for a
sound pass).

    .venv/bin/python tools/bench/envelope_ceiling.py city --frames 12 --views 150 --envelope 2,10

``--raise H`` lifts every frame's eye by H scene units (along +Z) first: with ``--ball``,
how much of the gap comes from the eyes of the ball that reach below a floor (on the city
at 2,10, from an eye 1.7 above the ground, the ball reaches 0.3 below it).
"""

import argparse
import json
import os
import sys
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))

from core import DEFAULT_STRATEGY, Culler  # noqa: E402
from core.camera import Camera  # noqa: E402
from core.envelope import Envelope, sample_views  # noqa: E402
from core.errors import OccError  # noqa: E402
from core.lab.jobs import load_job, sample_names  # noqa: E402


def ceiling(scene, cameras, envelope, views, resolution=(640, 360), seed=1):
    """Per frame ``{"point", "envelope", "ceiling", "false_negatives"}`` (object counts)."""
    culler = Culler(scene, resolution, strategy=DEFAULT_STRATEGY)
    rng = np.random.default_rng(seed)
    rows = []
    try:
        for cam in cameras:
            point = ~culler.cull(cam).visible
            r = culler.cull(cam, envelope=envelope)
            hidden = ~r.visible
            seen = culler.truth(cam).copy()
            for view in sample_views(cam, r.envelope, views, rng):      # above its floor, if it has one
                seen |= culler.truth(view)
            rows.append({"point": int(point.sum()), "envelope": int(hidden.sum()),
                         "ceiling": int((~seen).sum()), "false_negatives": int((hidden & seen).sum())})
    finally:
        culler.close()
    return rows


def raised(camera, height):
    """``camera`` with its eye ``height`` higher (+Z), looking the same way."""
    view = camera.view.copy()
    view[:3, 3] = -view[:3, :3] @ (camera.eye + np.array([0.0, 0.0, height]))
    return Camera(view, camera.projection)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", choices=sample_names())
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--views", type=int, default=150, help="sampled views of the envelope per frame")
    ap.add_argument("--envelope", default="2,10", help="D,A: distance (scene units), angle (degrees)")
    ap.add_argument("--raise", dest="lift", type=float, default=0.0, help="lift every eye this much (+Z)")
    ap.add_argument("--ball", action="store_true",
                    help="the whole ball of eyes (live mode's envelope keeps them off the nearest face)")
    ap.add_argument("--json", action="store_true", help="print the rows and sums as JSON")
    args = ap.parse_args(argv)
    try:
        envelope = Envelope.parse(args.envelope)
        envelope = replace(envelope, above_floor=not args.ball)
        if args.frames < 1 or args.views < 1:
            raise OccError("--frames and --views must be at least 1")
    except (OccError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    scene, cameras, _ = load_job(args.scene, None, args.frames)
    if args.lift:
        cameras = [raised(c, args.lift) for c in cameras]
    rows = ceiling(scene, cameras, envelope, args.views)
    total = {k: sum(r[k] for r in rows) for k in rows[0]}
    total["envelope_of_ceiling"] = total["envelope"] / max(total["ceiling"], 1)
    total["ceiling_of_point"] = total["ceiling"] / max(total["point"], 1)
    total["envelope_of_point"] = total["envelope"] / max(total["point"], 1)
    if args.json:
        print(json.dumps({"rows": rows, "total": total}))
        return 0
    print(f"{'frame':>5} {'point':>7} {'envelope':>9} {'ceiling':>8} {'FN':>4}")
    for i, r in enumerate(rows):
        print(f"{i:>5} {r['point']:>7} {r['envelope']:>9} {r['ceiling']:>8} {r['false_negatives']:>4}")
    print(f"envelope / ceiling {total['envelope_of_ceiling']:.3f}, ceiling / point {total['ceiling_of_point']:.3f}, "
          f"envelope / point {total['envelope_of_point']:.3f}, FN {total['false_negatives']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
