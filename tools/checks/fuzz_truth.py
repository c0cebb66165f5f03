"""Search for false negatives: seeded random scenes and camera walks, every pass of
every strategy checked against the object-ID truth at the query resolution and,
with ``display=``, at the display resolution.

    .venv/bin/python tools/checks/fuzz_truth.py --seeds 0-99 --strategies gpu,auto,om_coherent
    .venv/bin/python tools/checks/fuzz_truth.py --seeds 0-99 --envelope     (envelope passes)
    .venv/bin/python tools/checks/fuzz_truth.py --seeds 0-99 --envelope --ortho 1   (every view parallel)

Each seed draws a scene (rotated slabs and boxes of random size, some thin, some
tiny, some far; a ground; a world offset up to 1e6), a query resolution (odd sizes
included) and a walk of small steps, turns, cuts and orthographic views.  A seed
that hides a truly visible object prints the seed, the pass and the objects, and
the exit status is 1.  Runs on the machine's GL (llvmpipe here); no GPU needed.
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

from core import Camera, Culler, Scene, Visibility  # noqa: E402
from core.gl.context import create_context  # noqa: E402

BOX_V = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float64) - 0.5
BOX_F = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
# a single triangle: zero thickness, one side
TRI_V = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, 0.5, 0.0]])
TRI_F = np.array([[0, 1, 2]])


def rotation(rng):
    q = rng.normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                     [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                     [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])


def scene_for(seed):
    """A seeded scene: ``(Scene, offset, size)``."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 400))
    size = float(10.0 ** rng.uniform(-1, 3))
    offset = rng.uniform(-1, 1, 3) * (10.0 ** rng.choice([0, 3, 6]))
    mats, mesh = [], []
    ground = np.eye(4)
    ground[:3, :3] = np.diag([2.4 * size, 2.4 * size, 0.01 * size])
    ground[:3, 3] = offset + [0, 0, -0.005 * size]
    mats.append(ground)
    mesh.append(0)
    for _ in range(n - 1):
        m = np.eye(4)
        kind = rng.random()
        if kind < 0.5:                                        # buildings
            scale = rng.uniform(0.01, 0.12, 3) * size
        elif kind < 0.75:                                     # walls and slabs, some very thin
            scale = np.array([rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.4),
                              10.0 ** rng.uniform(-6, -2)]) * size
        else:                                                 # small things
            scale = rng.uniform(1e-4, 5e-3, 3) * size
        rot = rotation(rng) if rng.random() < 0.6 else np.eye(3)
        m[:3, :3] = rot @ np.diag(scale)
        m[:3, 3] = offset + np.r_[rng.uniform(-size, size, 2), rng.uniform(0, 0.15 * size)]
        mats.append(m)
        mesh.append(1 if rng.random() < 0.1 else 0)
    names = [f"o{i}" for i in range(n)]
    scene = Scene.from_arrays(names, [(BOX_V, BOX_F), (TRI_V, TRI_F)], np.array(mesh), np.array(mats))
    return scene, offset, size


def walk_for(seed, offset, size, frames, far_range=(3, 8), ortho_share=0.1):
    """A seeded camera walk: small steps and turns, cuts, now and then (``ortho_share`` of
    the views) an orthographic view, half of them clipped as Blender clips its own (a slab
    from half the far distance behind the eye); the far plane ``far_range`` times the
    scene's size (below 2: it cuts the scene)."""
    rng = np.random.default_rng(seed + 10_000)
    fov, aspect = rng.uniform(20, 110), rng.uniform(0.5, 2.5)
    near = size * 10.0 ** rng.uniform(-5, -2)
    far = size * rng.uniform(*far_range)
    eye = offset + np.r_[rng.uniform(-size, size, 2), rng.uniform(0.005, 0.3) * size]
    yaw = rng.uniform(0, 2 * np.pi)
    cams = []
    for _ in range(frames):
        r = rng.random()
        if r < 0.15:                                          # a cut
            eye = offset + np.r_[rng.uniform(-size, size, 2), rng.uniform(0.005, 0.3) * size]
            yaw = rng.uniform(0, 2 * np.pi)
        else:                                                 # a step and a small turn
            eye = eye + np.r_[rng.normal(0, 0.01 * size, 2), 0.0]
            yaw += rng.normal(0, 0.03)
        pitch = rng.uniform(-0.4, 0.2)
        d = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
        ortho = size * rng.uniform(0.05, 0.5) if rng.random() < ortho_share else None
        slab = ortho is not None and rng.random() < 0.5
        cams.append(Camera.look_at(eye, eye + d, up=(0, 0, 1), fov_y_deg=fov, aspect=aspect,
                                   near=-0.5 * far if slab else near, far=far, ortho_height=ortho))
    return cams


def parse_seeds(text):
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def search(seeds, strategies, frames, ctx, report=print, ortho_share=0.1):
    """Every strategy over every seed's walk: ``(passes, truly visible, culled as
    occluded, [(seed, strategy, pass, resolution, display, missed names), ...])``."""
    passes, seen, occluded, failures = 0, 0, 0, []
    for seed in seeds:
        rng = np.random.default_rng(seed + 20_000)
        res = (int(rng.integers(31, 330)), int(rng.integers(23, 200)))
        display = (res[0] * 2 + 1, res[1] * 2 + 1) if rng.random() < 0.3 else None
        scene, offset, size = scene_for(seed)
        cams = walk_for(seed, offset, size, frames, ortho_share=ortho_share)
        for name in strategies:
            with Culler(scene, res, strategy=name, ctx=ctx, display=display) as c:
                for k, cam in enumerate(cams):
                    truth = c.renderer.visible_truth(cam, display=display is not None)
                    r = c.cull(cam, truth=truth if name == "oracle" else None)
                    passes += 1
                    occluded += int((r.state == Visibility.OCCLUDED).sum())
                    seen += int(truth.sum())
                    missed = np.flatnonzero(truth & ~r.visible)
                    if len(missed):
                        failures.append((seed, name, k, res, display, [scene.names[i] for i in missed[:8]]))
                        report(f"FN seed {seed} {name} pass {k} res {res} display {display}: {failures[-1][-1]}")
    return passes, seen, occluded, failures


def envelope_search(seeds, frames, ctx, views=8, report=print, ortho_share=0.1):
    """Envelope passes over every seed's walk (a seeded envelope per seed, far planes that
    may cut the scene; half of them may keep their eyes above a floor, as live mode's do),
    each against the object-ID truth of ``views`` seeded views of the envelope the pass
    used: ``(passes, hidden, [(seed, pass, envelope, missed names), ...])``."""
    from core.envelope import Envelope, sample_views
    passes, hidden, failures = 0, 0, []
    for seed in seeds:
        rng = np.random.default_rng(seed + 30_000)
        res = (int(rng.integers(31, 330)), int(rng.integers(23, 200)))
        scene, offset, size = scene_for(seed)
        cams = walk_for(seed, offset, size, frames, far_range=(0.3, 4), ortho_share=ortho_share)
        env = Envelope(size * 10.0 ** rng.uniform(-4, -1.5), rng.uniform(0, 20), any_roll=bool(rng.random() < 0.5),
                       above_floor=bool(rng.random() < 0.5))
        with Culler(scene, res, ctx=ctx) as c:
            for k, cam in enumerate(cams):
                r = c.cull(cam, envelope=env)
                passes += 1
                hide = ~r.visible
                hidden += int(hide.sum())
                seen = np.zeros(len(scene), dtype=bool)
                for view in sample_views(cam, r.envelope, views, rng):     # (above its floor, if it found one)
                    seen |= c.renderer.visible_truth(view)
                missed = np.flatnonzero(seen & hide)
                if len(missed):
                    failures.append((seed, k, env, [scene.names[i] for i in missed[:8]]))
                    report(f"FN seed {seed} envelope pass {k} {env}: {failures[-1][-1]}")
    return passes, hidden, failures


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-19", help="e.g. 0-99 or 3,7,11")
    ap.add_argument("--strategies", default="gpu,auto,om_coherent,om_multi,two_pass")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--envelope", action="store_true",
                    help="envelope passes (a seeded envelope per seed) against seeded views of it")
    ap.add_argument("--ortho", type=float, default=0.1, help="the share of orthographic views in the walks")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.envelope:
        passes, hidden, failures = envelope_search(parse_seeds(args.seeds), args.frames, create_context(),
                                                   report=lambda line: print(line, flush=True),
                                                   ortho_share=args.ortho)
        print(f"{passes} envelope passes ({hidden} objects hidden), {len(failures)} with false negatives, "
              f"{time.perf_counter() - t0:.0f} s")
        return 1 if failures else 0
    passes, seen, occluded, failures = search(parse_seeds(args.seeds), args.strategies.split(","), args.frames,
                                              create_context(), report=lambda line: print(line, flush=True),
                                              ortho_share=args.ortho)
    print(f"{passes} passes ({seen} truly visible, {occluded} culled as occluded), "
          f"{len(failures)} with false negatives, {time.perf_counter() - t0:.0f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
