"""Live culling: a timer re-culls, debounced, after every change that can change
what is visible: the view moved (polled: navigation fires no depsgraph update),
or anything else changed (the change bus of :mod:`.handlers`: edits, frames,
"never cull"; :func:`changed` is subscribed to it when the add-on registers), or a
setting that changes what may be hidden (polled, :func:`..props.settings_key`).  GUI only.

Passes run beside the interface: a tick reads what the pass needs and hands the cull
to the engine thread (:meth:`.session.Session.begin`); a later tick lands it
(:meth:`.session.Session.finish`) only if nothing changed meanwhile (the change bus,
the settings, the view layer, the objects, what the view draws) and the view is
still inside the envelope its set holds for.  Otherwise it is dropped, and hides nothing.

While the view moves: every hidden set holds for an envelope around the view it was
made from (:mod:`..core.envelope`; a pass at rest takes a small one).  Before every
redraw of the culled viewport (:func:`guard`, a draw handler) and at every tick, the
view is checked against it with room for the next step of the measured motion; a
view about to leave it shows everything at once (:func:`leave`).  A pass during
motion starts from the current view once the displayed set would not last until a
pass started now lands; its envelope is sized from the motion and the passes' time
(:class:`..core.motion.LiveLoop`, the one copy of these decisions, which the motion
benchmark replays).  Without live mode (a Cull click), leaving shows everything too.

No Blender object is held between ticks (undo and file loads replace them):
the tick reads ``bpy.context.scene`` each time, and ``scene.occ.live`` is the
one truth.  After an undo or redo the timer follows the restored flag
(:func:`resync`); a file always opens with live mode off (:func:`after_load`).
Headless Blender runs no timers: a script drives :func:`_tick` and lands the pass in
flight with :func:`settle`.
"""

import time
import traceback
from dataclasses import dataclass

import bpy
import numpy as np

from ..core import OccError
from ..core.camera import camera_cut
from ..core.motion import AT_REST, LiveLoop, MotionTracker, occluded_share
from . import bus, identity, overlay, policy, shading, visibility
from .cameras import camera_for, find_viewport, region_camera, view_state
from .drawn import NoView, base_shown, drawn
from .passes import shown_by
from .props import settings_key
from .session import POLICY, SESSION, render_thread, rendering

POLL_S = 0.1          # timer period at rest
FLIGHT_POLL_S = 0.02  # ... while the view moves or a pass is in flight (its landing is polled)
DEBOUNCE_S = 0.15     # the view (or the scene) must rest this long before a pass at rest

# live mode's decisions while the view moves (core.motion.LiveLoop: the motion benchmark
# replays the same); its tracker measures the view's motion between looks (redraws, ticks)
LOOP = LiveLoop(POLICY)


@dataclass(frozen=True)
class Flight:
    """What a pass in flight was begun under: it lands only if all of it still holds.
    changes: the bus's count; settings: :func:`..props.settings_key`; view_state: the
    watched view's :func:`.cameras.view_state` (None: the scene camera); rest: a pass at
    rest (it may start fresh and marks the view as passed, :func:`_is_cut`)."""

    changes: int
    settings: tuple
    view_state: object
    rest: bool


@dataclass
class Watch:
    """What live mode keeps between ticks and redraws (no Blender object: undo and file
    loads replace them)."""

    last_view: np.ndarray | None = None   # the view (camera and display) at the last tick
    changed_at: float | None = None       # when the view last moved (None: a pass began since)
    dirty_at: float | None = None         # when something else first changed since a pass at rest began
    passed: tuple | None = None           # (camera, display) of the last pass at rest (:func:`_is_cut`)
    settings: tuple | None = None         # props.settings_key at the last tick (polled: no callbacks)
    changes: int = 0                      # changes the bus announced (a pass in flight lands only if none came)
    moving: bool = False                  # the view moved at the last tick
    leaving: bool = False                 # a leave timer is registered ...
    leave_for: int = -1                   # ... for the set of this SESSION.version
    region: int | None = None             # the watched 3D view's region data (:func:`track`) ...
    view_state: object = None             # ... and what it drew then (:func:`.cameras.view_state`)
    flight: Flight | None = None          # what the pass in flight was begun under, if live began it

    def forget_view(self, now: float | None = None) -> None:
        """Forget the view: the next tick records it (``now``: as if it moved then)."""
        self.last_view, self.changed_at, self.dirty_at, self.passed, self.moving = None, now, None, None, False


WATCH = Watch()

# what became of live's passes since the add-on loaded (read by tools/bench/gui_walk.py):
# begun; landed; dropped_left: the view had left its envelope when it finished;
# dropped_not_worth: a set during motion that would not pay for Blender's update;
# dropped_WHAT: WHAT changed under it (:func:`_changed_under`)
COUNTS = {"begun": 0, "landed": 0, "dropped_left": 0}


def track(context):
    """After a pass in a window: the 3D view it hides in is the one the redraw guard
    watches (a Cull click culls the view it was pressed in, live mode the view a timer
    finds; from the scene camera, the view that looks through it)."""
    found = _culled_viewport(context)
    region = None if found is None else found[2].as_pointer()
    if region != WATCH.region:
        LOOP.tracker = MotionTracker()                # what it measured was another view's motion
    WATCH.region = region
    WATCH.view_state = None if found is None else view_state(found[0].spaces.active)


def _culled_viewport(context):
    """The 3D view a pass hides in (:func:`.cameras.find_viewport`): the viewport source's,
    and in a window the scene camera's too (the view that must look through it)."""
    if context.scene.occ.source == "VIEWPORT" or not bpy.app.background:
        return find_viewport(context)
    return None


def _view_changed(space):
    """Whether the watched view now draws other objects than at the pass (local view
    entered or left, a type filter toggled): the hidden set no longer holds."""
    return WATCH.region is not None and view_state(space) != WATCH.view_state


def observe(camera):
    """Measure the motion since the last look at the view (:class:`..core.motion.MotionTracker`)."""
    LOOP.look(camera, time.perf_counter())


def _unsafe(camera):
    return not LOOP.holds(SESSION.shown, camera)


def guard():
    """Before a redraw of the culled viewport (a draw handler, so cheap): a view about
    to leave the hidden set's envelope makes :func:`leave` run at once (a timer: data
    cannot change while drawing).  It looks at the view while nothing is hidden too: the
    next Cull click's set is then measured against the view's last step, not against a
    view left long ago (taken for one step of a motion, it made that set go at once)."""
    if WATCH.leaving:
        return
    context = bpy.context
    if context.scene is None:
        return
    rv3d = context.region_data
    if rv3d is None or rv3d.as_pointer() != WATCH.region:
        return                                        # another view's redraw
    if context.scene.occ.source != "VIEWPORT":        # the camera's set (its motion: guard_camera)
        if SESSION.shown is not None and _view_changed(context.space_data):   # out of the camera's view, ...
            _leave_soon()
        return
    camera = region_camera(rv3d)
    observe(camera)
    if SESSION.shown is not None and (_unsafe(camera) or _view_changed(context.space_data)):
        _leave_soon()


def _leave_soon():
    """Show the hidden set on screen from a timer at once (data cannot change while
    drawing, nor inside a handler's update), unless a pass lands before it runs (a set
    made after the change); headless Blender runs no timers, and a script that drives
    it calls :func:`_leave_timer` itself."""
    WATCH.leave_for = SESSION.version             # (a timer registered already: aimed at the set now)
    if WATCH.leaving:
        return
    WATCH.leaving = True
    if not bpy.app.background:
        bpy.app.timers.register(_leave_timer, first_interval=0.0)


def _leave_timer():
    if _busy():
        return FLIGHT_POLL_S                       # after the add-on's own long work, or a render
    try:
        if SESSION.version == WATCH.leave_for:    # else a newer set, made after it, holds
            leave()
    except Exception:  # a timer must not raise: show everything instead
        traceback.print_exc()
        SESSION.shown = None
        visibility.restore()
    finally:
        WATCH.leaving = False
    return None


def leave(*_args):
    """The view is leaving the hidden set's envelope: everything is shown (at once: a
    pass takes longer than a redraw), as the add-on's own change (it is no edit: a pass
    in flight may still land, and no motion pass waits for rest).  Live, the next tick
    starts a pass from the view where it is."""
    SESSION.show_all(bpy.context)


def edited(scene, data):
    """An edit not the add-on's own, or a new frame (a listener of the change bus;
    ``data``: it touched a datablock beside the scene): a moved, deleted, reshaped,
    re-lit or re-shaded object can uncover what a hidden set hides, so the set on screen
    is shown before the next redraw, after a Cull click as in live mode (which culls
    again once the scene rests).  A change of the scene alone (a selection, the active
    object, an eye clicked) or of a camera leaves it, unless it changed the rule or the
    lights the pass was made under, hid an object the pass left drawn, or moved the scene
    camera it was made from (a view's own camera: the redraw guard).  During a render job
    the render's own frames come from its thread and are no edit; an edit the user makes
    meanwhile (on the main thread) shows the set once the render ends (the timer waits)."""
    if SESSION.shown is None or SESSION.busy is not None:
        return                                     # (an analysis, a bake: their own frames)
    if render_thread():
        return                                     # (a render's own frames, from its thread)
    try:
        holds = not data and _scene_holds(scene)
    except Exception:  # a handler must not raise: the set no longer holds
        traceback.print_exc()
        holds = False
    if not holds:
        _leave_soon()


def _busy():
    """The add-on's own long work runs (its frames and updates are its own), or a render
    job (no data may change under it)."""
    return SESSION.busy is not None or rendering()


def _scene_holds(scene):
    """Whether a change of the scene alone leaves the set on screen as it was made: the
    same rule and lights, every object the pass left drawn still drawn (an eye clicked,
    an object's or a collection's, is a change of the scene alone), and for the scene
    camera, the same camera."""
    last, shown = SESSION.last, SESSION.shown
    if last is None or shown.camera is None:
        return False
    context = bpy.context
    space = _watched_space(context) if scene.occ.source == "VIEWPORT" else None
    if shading.key(shading.rule(context)) != last.rule_key or not _still_drawn(context.view_layer, last.drawn, space):
        return False
    if policy.hides_chosen(context.view_layer):
        return False                    # selected in the outliner (or by a script) while hidden
    if scene.occ.source != "CAMERA":
        return True                     # the view: the redraw guard checks it
    try:
        camera, _ = camera_for(context, scene)
    except OccError:
        return False
    return np.array_equal(camera.projection, shown.camera.projection) and shown.envelope.holds(shown.camera, camera)


def _still_drawn(view_layer, uids, space=None) -> bool:
    """Whether every object of ``uids`` (session ids) is drawn by ``view_layer`` (its
    eye, collection and monitor flags; one list of what it draws), and by 3D view
    ``space`` if given (its own collections' eyes too, where it has local collections)."""
    if not len(uids):
        return True
    shown = base_shown(view_layer) if space is None else None
    if shown is not None:
        now = identity.idents(shown)
    else:
        layer_uids = identity.uids(view_layer.objects)
        now = layer_uids[drawn(view_layer, layer_uids, NoView.BASE if space is None else space)]
    return bool(np.isin(uids, now).all())


def _watched_space(context):
    """The 3D view the redraw guard watches (the last pass's, :func:`track`), if open."""
    wm = context.window_manager
    if WATCH.region is None or wm is None:
        return None
    for area in (a for w in wm.windows for a in w.screen.areas if a.type == "VIEW_3D"):
        rv3d = area.spaces.active.region_3d
        if rv3d is not None and rv3d.as_pointer() == WATCH.region:
            return area.spaces.active
    return None


def changed():
    """Something other than the view changed: re-cull once it rests (a listener of
    the change bus, :mod:`.handlers`); a pass in flight will not land."""
    WATCH.changes += 1
    if WATCH.dirty_at is None:
        WATCH.dirty_at = time.perf_counter()


def _is_cut(passed, camera, display):
    """Whether the view jumped since the last pass at rest (``passed``: its camera and
    display size): the one definition of a cut (:func:`..core.camera.camera_cut`), or
    another display size.  After a cut the strategy starts fresh."""
    if passed is None:
        return True
    before, shown = passed
    size = SESSION.culler.scene_size if SESSION.culler is not None else 0.0
    return tuple(shown) != tuple(display) or camera_cut(before, camera, size)


def _watched_state(context):
    found = _culled_viewport(context)
    return None if found is None else view_state(found[0].spaces.active)


def _begin(context, camera, display, now, fresh, rest):
    """Start a pass beside the interface: at rest (the rest envelope, hiding what it may)
    or during motion (the envelope :class:`..core.motion.LiveLoop` sizes)."""
    dirty = WATCH.dirty_at
    envelope = LOOP.start(camera, now, SESSION.culler.scene_size if SESSION.culler is not None else None,
                          envelope=AT_REST if rest else None)
    try:
        SESSION.begin(context, camera, display, fresh=fresh, envelope=envelope, beside=True)
    except BaseException:
        LOOP.drop()
        raise
    # the pass's own reads and update are not a change
    WATCH.dirty_at = dirty
    WATCH.flight = Flight(WATCH.changes, settings_key(context.scene.occ), _watched_state(context), rest)
    COUNTS["begun"] += 1


def _land(context, camera, display, now):
    """A pass in flight that finished lands (its set applied) or is dropped: see the
    module's doc.  Returns whether one landed."""
    pending = SESSION.pending
    if pending is None or WATCH.flight is None:
        if LOOP.flight is not None:                   # dropped by another pass (a Cull click, a reset)
            LOOP.drop()
        WATCH.flight = None
        return False
    if not pending.job.done():
        return False
    flight, WATCH.flight = WATCH.flight, None
    context.view_layer.update()                       # edits still pending reach the bus now
    try:
        result = pending.job.result()
    except Exception as e:  # noqa: BLE001 -- handed to finish below, which raises it here
        result, failed = None, e
    else:
        failed = None
    why = _changed_under(context, display, flight, pending) if failed is None else "failed"
    shown = shown_by(result, pending.camera) if failed is None else None
    lands = LOOP.land(shown, camera, now, _hidden_share(result)) and shown is not None
    if failed is not None:
        SESSION.finish(context, pending)              # raises the engine's error (the tick reports it)
    if why is not None or not lands:
        key = f"dropped_{why or ('not_worth' if LOOP.unworthy else 'left')}"
        COUNTS[key] = COUNTS.get(key, 0) + 1
        SESSION.discard()
        if flight.rest and WATCH.changed_at is None and WATCH.dirty_at is None:
            WATCH.changed_at = now                # at rest a pass must land: another once it rests
        return False
    SESSION.finish(context, pending)
    COUNTS["landed"] += 1
    if SESSION.last is not None and SESSION.last.changed:
        LOOP.updated(SESSION.last.blender_ms)         # what the next set during motion must pay for
    track(context)
    if flight.rest:
        WATCH.passed = (pending.camera, pending.display)
    return True


def _hidden_share(result):
    """What ``result``'s set may save of a redraw (:meth:`..core.motion.LivePolicy.worth`);
    None: no answer."""
    culler = SESSION.culler
    if result is None or culler is None or len(result.state) != len(culler.scene):
        return None
    return occluded_share(result.state, culler.scene.triangle_counts)


def _changed_under(context, display, flight, pending):
    """What changed since ``pending`` began, that its set may no longer hold for (None:
    nothing): the change bus, the display size, the settings, the session (its engine, the
    view layer, the objects) or what the watched view draws."""
    checks = (("bus", lambda: flight.changes == WATCH.changes),
              ("display", lambda: pending.display == tuple(display)),
              ("settings", lambda: flight.settings == settings_key(context.scene.occ)),
              ("session", lambda: SESSION.current(context, pending)),
              ("view", lambda: flight.view_state == _watched_state(context)))
    return next((name for name, holds in checks if not holds()), None)


def settle():
    """Wait for the pass in flight and land it (or drop it) as the next tick would:
    scripts and tests (headless Blender runs no timers); what a tick raises, raised."""
    pending = SESSION.pending
    if pending is None:
        return False
    pending.job.wait()
    context = bpy.context
    camera, display = camera_for(context)
    observe(camera)
    return _land(context, camera, display, time.perf_counter())


def _tick():
    try:
        context = bpy.context
        scene = context.scene
        if scene is None or not scene.occ.live:
            _drop_timer()                             # the flag is the truth: no timer without it
            return None
        camera, display = camera_for(context)
    except OccError:                                  # no camera, no viewport: nothing to cull for, show all
        visibility.restore()
        return POLL_S
    except ReferenceError:                            # data replaced under us: next tick reads it again
        return POLL_S
    if SESSION.busy:                                  # a modal cull or analysis holds the session
        return POLL_S
    if SESSION.left_layer(context):                   # another layer: what was hidden for the last is shown
        changed()                                     # ... and a fresh pass decides here
    settings = settings_key(scene.occ)
    if settings != WATCH.settings:                    # what may be hidden changed: a fresh pass
        if WATCH.settings is not None:
            changed()
        WATCH.settings = settings
    key = np.concatenate([camera.view.ravel(), camera.projection.ravel(), display])
    now = time.perf_counter()
    observe(camera)
    try:
        _land(context, camera, display, now)
        found = _culled_viewport(context)
        if found is not None and _view_changed(found[0].spaces.active) and SESSION.shown is not None:
            WATCH.dirty_at = now                      # it draws other objects now: a fresh pass next
            leave()
        elif _unsafe(camera):                         # the redraw guard missed it: leave now
            leave()
        moved = WATCH.last_view is None or not np.array_equal(key, WATCH.last_view)
        WATCH.moving = moved
        if moved:
            WATCH.last_view, WATCH.changed_at = key, now
            # during motion: a pass from here once the displayed set would not last until
            # it lands (no scene change pending: that is a fresh pass's, at rest)
            if (SESSION.pending is None and SESSION.culler is not None and WATCH.passed is not None
                    and WATCH.dirty_at is None and LOOP.due(SESSION.shown, camera)):
                _begin(context, camera, display, now, fresh=False, rest=False)
            return _period()
        rested = [t for t in (WATCH.changed_at, WATCH.dirty_at) if t is not None]
        if rested and now - max(rested) >= DEBOUNCE_S and SESSION.pending is None:
            fresh = WATCH.dirty_at is not None or _is_cut(WATCH.passed, camera, display)
            WATCH.changed_at = WATCH.dirty_at = None
            _begin(context, camera, display, now, fresh=fresh, rest=True)
    except OccError as e:  # the user's to fix (an empty scene, a panoramic camera): show all, keep going
        print(f"occlusion culling: {e}")
        WATCH.passed = WATCH.flight = None
        SESSION.discard()
        LOOP.drop()
        SESSION.shown = None
        visibility.restore()
    except Exception:  # a timer must not raise: our bug, live mode stops and shows everything
        traceback.print_exc()
        print("occlusion culling stopped (details above)")
        WATCH.flight = None
        SESSION.reset()
        LOOP.drop()
        visibility.restore()
        stop(context)
        return None
    return _period()


def _period():
    """The next tick: soon while a pass is in flight or the view moves, else at rest's pace."""
    return FLIGHT_POLL_S if SESSION.pending is not None or WATCH.moving else POLL_S


def _ensure_timer():
    if not bpy.app.timers.is_registered(_tick):
        bpy.app.timers.register(_tick, first_interval=0.0)


def _drop_timer():
    if bpy.app.timers.is_registered(_tick):
        bpy.app.timers.unregister(_tick)


_guard_handle = []


def install():
    """The redraw guard (a draw handler of every 3D view, before the view is drawn) and
    the overlay, once (GUI only): after every pass that leaves a hidden set with an
    envelope (a Cull click too: leaving its envelope shows everything)."""
    if not bpy.app.background and not _guard_handle:
        _guard_handle.append(bpy.types.SpaceView3D.draw_handler_add(guard, (), "WINDOW", "PRE_VIEW"))
    overlay.install()


def uninstall():
    while _guard_handle:
        bpy.types.SpaceView3D.draw_handler_remove(_guard_handle.pop(), "WINDOW")
    overlay.uninstall()


def _listens():
    """What live mode listens to on the change bus (:mod:`.bus`)."""
    return (("changed", changed), ("edited", edited), ("camera", guard_camera), ("loaded", after_load),
            ("undone", resync))


def register():
    for event, listener in _listens():
        bus.subscribe(event, listener)


def unregister():
    for event, listener in reversed(_listens()):
        bus.unsubscribe(event, listener)


def start(context):
    install()
    context.scene.occ.live = True
    WATCH.forget_view(time.perf_counter())
    WATCH.settings = settings_key(context.scene.occ)
    _ensure_timer()


def stop(context):
    context.scene.occ.live = False
    _drop_timer()
    WATCH.forget_view()
    if WATCH.flight is not None:                     # live's pass in flight lands nowhere
        WATCH.flight = None
        SESSION.discard()
    LOOP.drop()


def stop_all():
    """Live off everywhere (the add-on goes away)."""
    _drop_timer()
    if isinstance(bpy.data, bpy.types.BlendData):
        for scene in bpy.data.scenes:
            if scene.occ.live:
                scene.occ.live = False


def after_load():
    """A file opens with live mode off: what it hid was restored, and nothing runs
    until the user starts it."""
    stop_all()


def resync():
    """After undo or redo: the timer runs exactly when the restored flag says live,
    and the restored scene is culled again; what the restored data hides, hidden for a
    view nobody recorded (:data:`.passes.UNKNOWN`), is shown before the next redraw
    (from the scene camera too, which no redraw guard watches)."""
    if SESSION.shown is not None and SESSION.shown.camera is None:
        _leave_soon()
    scene = bpy.context.scene
    if scene is not None and scene.occ.live:
        _ensure_timer()
        changed()
    else:
        _drop_timer()


# the scene camera's motion, from frame to frame (guard_camera)
CAMERA_TRACKER = MotionTracker()


def guard_camera(scene):
    """Live from the scene camera, a new frame (playback, scrubbing) or an edit moves
    it (the depsgraph and frame-change handlers call this): where it is about to leave
    the hidden set's envelope, everything is shown before the frame is drawn (the
    live pass that follows hides again).  The camera is watched while nothing is hidden
    too: a set that lands after the camera came to rest is measured against its last
    frame, not against one seen frames back (taken for one step, it let the set go)."""
    if SESSION.busy or not scene.occ.live or scene.occ.source != "CAMERA":
        return
    try:
        camera, _ = camera_for(bpy.context, scene)
    except OccError:
        camera = None
    if camera is None:
        CAMERA_TRACKER.view = None
    else:
        CAMERA_TRACKER.observe(camera, time.perf_counter())
    if SESSION.shown is None:        # nothing hidden (or evaluating the camera ran this handler again: shown)
        return
    centre, envelope = SESSION.shown
    if camera is None or centre is None or not CAMERA_TRACKER.safe(POLICY, centre, envelope, camera):
        SESSION.shown = None
        visibility.restore()
