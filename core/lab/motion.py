"""The motion benchmark: replays motions under the live policy (:mod:`core.motion`).

``python -m core motion SCENE`` replays each motion (:data:`MOTIONS`) at 30 Hz as live
mode runs it (:func:`replay`: its decisions, :class:`core.motion.LiveLoop`, with passes
that land when they finish) and counts, at every step drawn, the objects the object-ID truth sees that the
displayed set hides (visible-but-hidden object-steps; the target is 0), the share of
the ideal culling held on screen, and the triangles drawn against frustum culling alone.
"""

import math
import time

import numpy as np

from ..camera import Camera, look_at
from ..frustum import classify, planes_from_matrix
from ..motion import LiveLoop, occluded_share

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


def frustum_mask(camera, bounds):
    """``(n,) bool``: the objects whose boxes meet ``camera``'s frustum (what Blender's
    own frustum culling draws)."""
    rel = bounds - camera.eye                    # camera-relative: far from the origin stays exact
    outside, _ = classify(planes_from_matrix(camera.relative_view_projection()), rel)
    return ~outside


def replay(culler, views, policy=None, latency_s=None, update_ms=None):
    """Replay ``views`` (a look every :data:`STEP_S` of wall time) as live mode runs them,
    through its own decisions (:class:`core.motion.LiveLoop`): a pass at rest hides before
    the motion; at every step a pass in flight that has finished lands (its set is shown
    if the view is still inside its envelope), the step is drawn and counted, a displayed
    set the next step would leave is shown first, and a pass starts from the view once
    the displayed set would not last until it lands.

    Passes run beside the interface (live mode's engine thread): every step is drawn, and
    a pass lands at the first step after its measured time (or ``latency_s`` when given:
    a fixed latency, so the counts do not depend on this machine's speed).  The time is
    the engine's pass only: the add-on's reads before it and Blender's update after a
    hide hold Blender's main thread on top, in Blender.  ``update_ms``: Blender's update
    after every set that changes what is hidden, as live mode measures it (None: not
    modelled): a set during motion then lands only where it pays for it
    (:meth:`core.motion.LivePolicy.worth`).

    Returns per drawn step rows and the pass times (ms)."""
    loop = LiveLoop(policy)
    bounds = culler.scene.bounds
    tris = np.asarray(culler.scene.triangle_counts, dtype=np.int64)
    nothing = np.zeros(len(bounds), dtype=bool)

    def run(view, envelope, probe=False):
        t = time.perf_counter()
        r = culler.cull(view, envelope=envelope, probe=probe)
        ms = 1e3 * (time.perf_counter() - t)
        pass_ms.append(ms)
        share = occluded_share(r.state, tris) if update_ms is not None else None
        return ~r.visible, (view, r.envelope), (latency_s if latency_s is not None else ms / 1e3), share

    def shows(h):
        nonlocal hidden
        if update_ms is not None and not np.array_equal(h, hidden):
            loop.updated(update_ms)
        hidden = h

    pass_ms, rows = [], []
    loop.look(views[0], 0.0)
    loop.start(views[0], 0.0, envelope=loop.policy.rest(culler.scene_size))
    hidden = nothing
    h, shown, took, share = run(views[0], loop.flight.envelope, probe=True)   # at rest: hidden before it moves
    loop.land(shown, views[0], took, share)
    shows(h)
    flight = None                        # (hidden, shown, when it lands, its share) of the pass in flight
    for k, view in enumerate(views):
        now = k * STEP_S
        loop.look(view, now)
        if flight is not None and now >= flight[2] - 1e-9:
            if loop.land(flight[1], view, now, flight[3]):
                shown = flight[1]
                shows(flight[0])
            flight = None
        truth = culler.truth(view)
        drawn = frustum_mask(view, bounds)
        # drawn outside the set's envelope: the check before a redraw cannot change what that
        # redraw draws (a motion's first step beyond the rest envelope, a step larger than the
        # margin allows): the only steps where a false negative may come from
        late = shown is not None and not shown[1].holds(shown[0], view)
        rows.append({"step": k, "late": late, "false_negatives": int((truth & hidden).sum()),
                     "hidden": int(hidden.sum()), "held": int((hidden & ~truth).sum()),
                     "ideal": int((~truth).sum()), "culling": bool(hidden.any()),
                     "triangles": int(tris[drawn & ~hidden].sum()), "triangles_vfc": int(tris[drawn].sum())})
        if not loop.holds(shown, view):                     # the next step leaves it: show all first
            hidden, shown = nothing, None
        if loop.due(shown, view):
            h, s, took, share = run(view, loop.start(view, now, culler.scene_size))
            flight = (h, s, now + max(took, STEP_S), share)
    return rows, pass_ms


def run_motion(culler, cameras, names=MOTIONS, latency_s=None, policy=None, progress=None, update_ms=None):
    """Every motion of :data:`MOTIONS` from ``cameras``: a report row each.  One pass
    at rest before them, not counted, warms the engine (its first pass after a build
    finds each mesh's polygons and compiles the GL's programs), as ``bench`` does: a
    replay's own pass at rest is timed and sizes its first envelopes."""
    rest = (policy or LiveLoop().policy).rest(culler.scene_size)
    culler.cull(cameras[0], envelope=rest, fresh=True)
    report = {}
    for name in names:
        views = motions(cameras, culler.scene_size, name)
        rows, pass_ms = replay(culler, views, policy, latency_s, update_ms)

        def total(key, rows=rows):
            return sum(r[key] for r in rows)
        report[name] = {
            "steps": len(views), "steps_drawn": len(rows), "passes": len(pass_ms),
            "false_negatives": total("false_negatives"), "steps_late": total("late"),
            "false_negatives_in_envelope": sum(r["false_negatives"] for r in rows if not r["late"]),
            "steps_culling": sum(r["culling"] for r in rows) / max(len(rows), 1),
            "hidden_mean": float(np.mean([r["hidden"] for r in rows])) if rows else 0.0,
            "ideal_mean": float(np.mean([r["ideal"] for r in rows])) if rows else 0.0,
            "held_share": total("held") / max(total("ideal"), 1),
            "triangles_mean": total("triangles") / max(len(rows), 1),
            "triangles_vfc_mean": total("triangles_vfc") / max(len(rows), 1),
            "pass_ms_median": float(np.median(pass_ms)) if pass_ms else 0.0,
        }
        if progress:
            progress(name, report[name])
    return report


def format_motion(report, title):
    head = (f"{'motion':<8} {'steps':>6} {'drawn':>6} {'passes':>6} {'FN':>5} {'late':>5} {'held %':>7} {'hidden':>8} "
            f"{'ideal':>8} {'tris/vfc':>8} {'pass ms':>8}")
    lines = [title, head, "-" * len(head)]
    for name, r in report.items():
        ratio = r["triangles_mean"] / r["triangles_vfc_mean"] if r["triangles_vfc_mean"] else 1.0
        lines.append(f"{name:<8} {r['steps']:>6d} {r['steps_drawn']:>6d} {r['passes']:>6d} "
                     f"{r['false_negatives']:>5d} {r['steps_late']:>5d} {100 * r['held_share']:>7.1f} "
                     f"{r['hidden_mean']:>8.1f} {r['ideal_mean']:>8.1f} {ratio:>8.2f} {r['pass_ms_median']:>8.1f}")
    lines.append("drawn: steps redrawn (passes run beside the interface); late: steps drawn outside the "
                 "set's envelope (a motion's first step beyond the rest envelope, a step beyond the margin)")
    lines.append("held %: of the objects the truth does not see, the share hidden on screen, over the steps "
                 "drawn; tris/vfc: triangles drawn against Blender's frustum culling alone")
    return "\n".join(lines)
