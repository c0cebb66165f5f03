"""What an orthographic view hides at rest: the point pass, the parallel envelope pass
(live mode's rest envelope, ``core.envelope``'s ``_ParallelProof``) and the same with
the perspective twin a window adds (``Envelope.also``: the perspective view Blender turns
an orthographic one into at an orbit's start), with each pass's time.

Each sample scene is seen whole from its centre along three directions (Front, Top and an
oblique user view), clipped as Blender clips a view (a slab either side of the eye); the
twin stands at the distance where Blender's 50 mm viewport lens shows the same width.
Every count is checked against the object-ID truth of VIEWS seeded views of the envelope
(the false negatives column: 0 for a sound pass).

    .venv/bin/python tools/bench/ortho_envelope.py assembly,city,cathedral --small
"""

import argparse
import math
import os
import sys
import time
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))

import sample_scenes  # noqa: E402
from core import Culler, Visibility  # noqa: E402
from core.camera import Camera, perspective  # noqa: E402
from core.envelope import Envelope, sample_views  # noqa: E402
from core.loading import load_scene  # noqa: E402
from core.motion import LivePolicy  # noqa: E402

VIEWS = {"Front": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), "Top": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
         "oblique": ((0.6, 0.5, -0.6), (0.0, 0.0, 1.0))}
LENS_MM, SENSOR_MM, ASPECT = 50.0, 72.0, 16 / 9


def views_of(culler):
    """``{name: (orthographic camera, its perspective twin)}`` around the scene's centre."""
    b = culler.scene.bounds
    lo, hi = b[:, 0].min(axis=0), b[:, 1].max(axis=0)
    centre, size = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    slab = max(500.0, size)
    height = 0.6 * size
    out = {}
    for name, (way, up) in VIEWS.items():
        d = np.array(way) / np.linalg.norm(way)
        ortho = Camera.look_at(centre, centre + d, up=up, ortho_height=height, aspect=ASPECT, near=-slab, far=slab)
        dist = height * ASPECT * LENS_MM / SENSOR_MM
        tan = SENSOR_MM / 2 / LENS_MM * 1.01
        proj = perspective(math.degrees(2 * math.atan(tan / ASPECT)), ASPECT, 0.01, 2 * slab)
        out[name] = (ortho, Camera(Camera.look_at(centre - d * dist, centre, up=up).view, proj))
    return out


def _seen(culler, views):
    seen = np.zeros(len(culler), dtype=bool)
    for view in views:
        seen |= culler.truth(view)
    return seen


def measure(culler, views, seed=0):
    """Rows ``(view, point, parallel, parallel ms, with twin, with twin ms, false negatives)``:
    occluded counts; the false negatives of the parallel pass against views of its envelope,
    and of the pass with the twin against views of both envelopes."""
    rest = LivePolicy().rest(culler.scene_size)
    env = Envelope(rest.distance, rest.angle_deg, any_roll=False)
    rng = np.random.default_rng(seed)
    rows = []
    for name, (ortho, twin) in views_of(culler).items():
        passes = []
        for envelope in (None, env, replace(env, also=(twin,))):
            t = time.perf_counter()
            r = culler.cull(ortho, envelope=envelope, fresh=True)
            passes.append((r, 1e3 * (time.perf_counter() - t)))
        (point, _), (par, par_ms), (both, both_ms) = passes
        seen_ortho = _seen(culler, sample_views(ortho, env, views, rng))
        seen_twin = _seen(culler, sample_views(twin, env, views, rng))
        fn = int((seen_ortho & ~par.visible).sum()) + int(((seen_ortho | seen_twin) & ~both.visible).sum())
        count = [int((r.state == Visibility.OCCLUDED).sum()) for r in (point, par, both)]
        rows.append((name, count[0], count[1], par_ms, count[2], both_ms, fn))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", help="sample scene names, comma separated")
    ap.add_argument("--small", action="store_true", help="the small sample scenes")
    ap.add_argument("--views", type=int, default=16, help="seeded views of each envelope to check against")
    args = ap.parse_args(argv)
    print("| scene | view | point pass | parallel envelope (ms) | with the twin (ms) | false negatives |")
    print("|---|---|---|---|---|---|")
    bad = 0
    for name in args.scenes.split(","):
        scene = load_scene(sample_scenes.scene_path(name, small=args.small))
        with Culler(scene, resolution=(640, 360)) as culler:
            for view, point, par, par_ms, both, both_ms, fn in measure(culler, args.views):
                print(f"| {name} | {view} | {point} | {par} ({par_ms:.0f}) | {both} ({both_ms:.0f}) | {fn} |",
                      flush=True)
                bad += fn
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
