"""Live culling while the view moves: the policy, and a benchmark that replays motions.

A pass hides a set that holds for an envelope around the view it was made from
(:mod:`core.envelope`).  The policy sizes the envelope from the measured motion: the
eye's speed and the turn rate, times the time until the pass lands plus how long it
should last after, plus a margin of a few steps of motion.  Before each redraw the
view is checked against the displayed set's envelope, with room for the next step:
a view about to leave it shows everything first (showing is urgent), and a new pass
starts from where the view is; its set is shown when it lands, if the view is still
inside its envelope.  At rest the envelope is small (:attr:`LivePolicy.rest_rel`,
:attr:`LivePolicy.rest_deg`): the first steps of a new motion stay in it, and the
check before the next redraw catches the rest.

``python -m core motion SCENE`` replays each motion (:data:`MOTIONS`) at 30 Hz under
this policy and counts, at every step, the objects the object-ID truth sees that the
displayed set hides (visible-but-hidden object-steps; the target is 0).
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from .camera import Camera, look_at
from .envelope import Envelope

STEP_S = 1.0 / 30.0          # a redraw at 30 Hz
STEPS_PER_FRAME = 4          # a sample path replayed as a drag: this many steps between its frames
MOTIONS = ("drag", "orbit", "dolly", "walk")
MAX_ANGLE_DEG = 30.0         # a wider envelope hides little; a faster turn shows all until it slows


@dataclass(frozen=True)
class LivePolicy:
    """How big an envelope a pass takes and when the displayed set must go."""

    hold_s: float = 0.5          # the envelope lasts this long after the pass lands, at the measured speed
    margin_steps: float = 2.0    # and this many steps of the last motion beyond that
    rest_rel: float = 0.002      # the envelope at rest: this share of the scene's size ...
    rest_deg: float = 2.0        # ... and this many degrees

    def envelope(self, speed, turn_deg_s, latency_s, step_move, step_turn_deg, scene_size):
        """The envelope of a pass that lands ``latency_s`` from now, the view moving at
        ``speed`` (scene units per second) and turning ``turn_deg_s``."""
        horizon = latency_s + self.hold_s
        d = max(speed * horizon + self.margin_steps * step_move, self.rest_rel * scene_size)
        a = max(turn_deg_s * horizon + self.margin_steps * step_turn_deg, self.rest_deg)
        # the turn measured is the frame's (roll included): a narrower view than any roll
        return Envelope(d, min(a, MAX_ANGLE_DEG), any_roll=False)

    def rest(self, scene_size):
        """The envelope of a pass made at rest: what the first steps of a motion need
        before the check before each redraw sees them."""
        return Envelope(self.rest_rel * scene_size, self.rest_deg, any_roll=False)

    def safe(self, centre, envelope, view, step_move, step_turn_deg):
        """Whether ``view`` and the next step (as large as ``margin_steps`` of the last)
        stay inside ``envelope`` around ``centre``."""
        if not np.array_equal(centre.projection, view.projection):
            return False                                          # another lens: the envelope says nothing
        move, turn = view_change(centre, view, frame=not envelope.any_roll)
        return (move + self.margin_steps * step_move <= envelope.distance
                and turn + self.margin_steps * step_turn_deg <= envelope.angle_deg)


def view_change(a, b, frame=True):
    """Eye distance and turn (degrees) between two cameras: the angle of the rotation
    from one camera frame to the other (roll included), or with ``frame=False`` only
    the angle between their view directions."""
    move = float(np.linalg.norm(a.eye - b.eye))
    if frame:
        ra, rb = a.view[:3, :3], b.view[:3, :3]
        ra = ra / np.linalg.norm(ra, axis=1, keepdims=True)      # rows: the camera's axes
        rb = rb / np.linalg.norm(rb, axis=1, keepdims=True)
        cos = float(np.clip((np.trace(ra @ rb.T) - 1.0) / 2.0, -1.0, 1.0))
    else:
        cos = float(np.clip(a.direction @ b.direction, -1.0, 1.0))
    return move, math.degrees(math.acos(cos))


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
