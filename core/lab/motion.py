"""The motion benchmark: replays motions under the live policy (:mod:`core.motion`).

``python -m core motion SCENE`` replays each motion (:data:`MOTIONS`) at 30 Hz under
:class:`core.motion.LivePolicy` and counts, at every step, the objects the object-ID
truth sees that the displayed set hides (visible-but-hidden object-steps; the target is 0).
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from ..camera import Camera, look_at
from ..envelope import Envelope
from ..motion import LivePolicy, view_change

STEP_S = 1.0 / 30.0          # a redraw at 30 Hz
STEPS_PER_FRAME = 4          # a sample path replayed as a drag: this many steps between its frames
MOTIONS = ("drag", "orbit", "dolly", "walk")


def _camera(eye, target, up, projection):
    return Camera(look_at(eye, target, up), projection)


def _up(camera):
    return np.linalg.inv(camera.view[:3, :3])[:, 1]


def motions(cameras, scene_size, name):
    """The views of one motion, a step each (:data:`STEP_S`), from a camera path."""
    first = cameras[0]
    proj, up = first.projection, _up(first)
    if name == "drag":                  # the path, interpolated: the user drags the view along it
        out = []
        for a, b in zip(cameras[:-1], cameras[1:], strict=True):
            for k in range(STEPS_PER_FRAME):
                f = k / STEPS_PER_FRAME
                eye = (1 - f) * a.eye + f * b.eye
                d = (1 - f) * a.direction + f * b.direction
                out.append(_camera(eye, eye + d, _up(a), a.projection))
        return out + [cameras[-1]]
    eye, d = first.eye, first.direction
    world_up = np.array([0.0, 0.0, 1.0]) if abs(up[2]) >= 0.5 else up
    if name == "orbit":                 # middle mouse: around a pivot ahead, 90 degrees a second, 3 s
        pivot = eye + d * 0.1 * scene_size
        out = []
        for k in range(90):
            a = math.radians(3.0 * k)
            r = _axis_rotation(world_up, a)
            e = pivot + r @ (eye - pivot)
            out.append(_camera(e, pivot, up, proj))
        return out
    if name == "dolly":                 # toward the view and back, 5 % of the scene a second, 2 s each way
        v = 0.05 * scene_size * STEP_S
        steps = [k for k in range(60)] + [60 - k for k in range(60)]
        return [_camera(eye + d * v * k, eye + d * (v * k + 1.0), up, proj) for k in steps]
    if name == "walk":                  # 1.4 units a second ahead, turning 30 degrees a second, 4 s
        flat = d - (d @ world_up) * world_up
        flat = flat / max(np.linalg.norm(flat), 1e-12)
        out, e = [], eye.copy()
        for k in range(120):
            h = _axis_rotation(world_up, math.radians(30.0 * STEP_S * k)) @ flat
            out.append(_camera(e, e + h + (d @ world_up) * world_up, world_up, proj))
            e = e + 1.4 * STEP_S * h
        return out
    raise ValueError(name)


def _axis_rotation(axis, angle):
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    x, y, z = axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


@dataclass
class Shown:
    """A pass's hidden set on screen: the view it was made from and its envelope."""

    centre: Camera
    envelope: Envelope
    hidden: np.ndarray


def replay(culler, views, policy=None, latency_s=0.1):
    """Replay ``views`` (a step each) under ``policy``; a pass lands ``latency_s``
    after it starts.  Returns per-step rows and the pass times (ms)."""
    policy = policy or LivePolicy()
    lag = max(1, math.ceil(latency_s / STEP_S - 1e-9))
    shown = pending = None
    prev = None
    step_move = step_turn = 0.0
    speeds, turns = [0.0], [0.0]
    rows, pass_ms = [], []
    for i, view in enumerate(views):
        if pending is not None and i >= pending[0]:
            cand = pending[1]
            pending = None
            if policy.safe(cand.centre, cand.envelope, view, step_move, step_turn):
                shown = cand
        truth = culler.truth(view)
        hidden = shown.hidden if shown is not None else np.zeros(len(truth), dtype=bool)
        rows.append({"false_negatives": int((truth & hidden).sum()), "hidden": int(hidden.sum()),
                     "culling": shown is not None})
        # after this redraw: the motion measured, the next redraw made safe
        if prev is not None:
            step_move, step_turn = view_change(prev, view)
            speeds = (speeds + [step_move / STEP_S])[-3:]
            turns = (turns + [step_turn / STEP_S])[-3:]
        prev = view
        if shown is not None and not policy.safe(shown.centre, shown.envelope, view, step_move, step_turn):
            shown = None                                          # show everything before the next redraw
        if shown is None and pending is None:
            env = policy.envelope(max(speeds), max(turns), lag * STEP_S, step_move, step_turn, culler.scene_size)
            t = time.perf_counter()
            r = culler.cull(view, envelope=env)
            pass_ms.append(1e3 * (time.perf_counter() - t))
            pending = (i + lag, Shown(view, env, ~r.visible))
    return rows, pass_ms


def run_motion(culler, cameras, names=MOTIONS, latency_s=0.1, policy=None, progress=None):
    """Every motion of :data:`MOTIONS` from ``cameras``: a report row each."""
    report = {}
    for name in names:
        views = motions(cameras, culler.scene_size, name)
        rows, pass_ms = replay(culler, views, policy, latency_s)
        report[name] = {
            "steps": len(rows), "passes": len(pass_ms),
            "false_negatives": int(sum(r["false_negatives"] for r in rows)),
            "steps_culling": sum(r["culling"] for r in rows) / max(len(rows), 1),
            "hidden_mean": float(np.mean([r["hidden"] for r in rows])) if rows else 0.0,
            "pass_ms_median": float(np.median(pass_ms)) if pass_ms else 0.0,
        }
        if progress:
            progress(name, report[name])
    return report


def format_motion(report, title):
    head = f"{'motion':<8} {'steps':>6} {'passes':>6} {'FN':>5} {'culling %':>9} {'hidden':>8} {'pass ms':>8}"
    lines = [title, head, "-" * len(head)]
    for name, r in report.items():
        lines.append(f"{name:<8} {r['steps']:>6d} {r['passes']:>6d} {r['false_negatives']:>5d} "
                     f"{100 * r['steps_culling']:>9.1f} {r['hidden_mean']:>8.1f} {r['pass_ms_median']:>8.1f}")
    return "\n".join(lines)
