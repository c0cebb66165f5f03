"""Live culling: a timer re-culls, debounced, after every change that can change
what is visible: the view moved (polled: navigation fires no depsgraph update),
or anything else changed (the change bus of :mod:`.handlers`: edits, frames,
"never cull"; :func:`changed` is subscribed to it when the add-on registers), or a
setting that changes what may be hidden (polled, :func:`..props.settings_key`).  GUI only.

While the view moves: every hidden set holds for an envelope around the view it
was made from (:mod:`..core.envelope`; a pass at rest takes a small one).  Before
every redraw of the culled viewport (:func:`guard`, a draw handler) and at every
tick, the view is checked against it with room for the next step of the measured
motion; a view about to leave it makes a pass during motion at once
(:func:`leave`): it shows what that pass finds visible and hides nothing new, and
its envelope is sized from the motion (:class:`..core.motion.LivePolicy`).  Hiding
waits for rest.  Without live mode (a Cull click), leaving shows everything.

No Blender object is held between ticks (undo and file loads replace them):
the tick reads ``bpy.context.scene`` each time, and ``scene.occ.live`` is the
one truth.  After an undo or redo the timer follows the restored flag
(:func:`resync`); a file always opens with live mode off (:func:`after_load`).
"""

import time
import traceback

import bpy
import numpy as np

from ..core import OccError
from ..core.camera import camera_cut
from ..core.motion import AT_REST, MotionTracker
from . import bus, overlay, visibility
from .cameras import camera_for, find_viewport, region_camera, scene_camera, view_state
from .props import settings_key
from .session import POLICY, SESSION

POLL_S = 0.1          # timer period
DEBOUNCE_S = 0.15     # the view (or the scene) must rest this long before a pass

# passed: (camera, display) of the last pass at rest, for telling a cut (:func:`_is_cut`)
# settings: props.settings_key at the last tick (polled: the settings have no update callbacks)
_state = {"last_view": None, "changed_at": None, "dirty_at": None, "passed": None, "settings": None}
# the view's motion, measured between successive looks (redraws and ticks): the
# tracker the motion benchmark replays too (core.lab.motion)
TRACKER = MotionTracker()
# leaving: a leave timer is registered; region, view_state: the watched 3D view (track)
_motion = {"leaving": False, "region": None, "view_state": None}


def track(context):
    """After a pass from the viewport: the 3D view it was made for is the one the redraw
    guard watches (a Cull click culls the view it was pressed in, live mode the view a
    timer finds)."""
    found = find_viewport(context) if context.scene.occ.source == "VIEWPORT" else None
    _motion["region"] = None if found is None else found[2].as_pointer()
    _motion["view_state"] = None if found is None else view_state(found[0].spaces.active)


def _view_changed(space):
    """Whether the watched view now draws other objects than at the pass (local view
    entered or left, a type filter toggled): the hidden set no longer holds."""
    return _motion["region"] is not None and view_state(space) != _motion["view_state"]


def observe(camera):
    """Measure the motion since the last look at the view (:class:`MotionTracker`)."""
    TRACKER.observe(camera, time.perf_counter())


def _unsafe(camera):
    shown = SESSION.shown
    return shown is not None and not TRACKER.safe(POLICY, shown.camera, shown.envelope, camera)


def guard():
    """Before a redraw of the culled viewport (a draw handler, so cheap): a view about
    to leave the hidden set's envelope makes :func:`leave` run at once (a timer: data
    cannot change while drawing)."""
    if SESSION.shown is None or _motion["leaving"]:
        return
    context = bpy.context
    if context.scene is None or context.scene.occ.source != "VIEWPORT":
        return
    rv3d = context.region_data
    if rv3d is None or rv3d.as_pointer() != _motion["region"]:
        return                                        # another view's redraw
    camera = region_camera(rv3d)
    observe(camera)
    if _unsafe(camera) or _view_changed(context.space_data):
        _motion["leaving"] = True
        bpy.app.timers.register(_leave_timer, first_interval=0.0)


def _leave_timer():
    try:
        context = bpy.context
        camera, display = camera_for(context)
        leave(context, camera, display)
    except Exception:  # a timer must not raise: show everything instead
        traceback.print_exc()
        SESSION.shown = None
        visibility.restore()
    finally:
        _motion["leaving"] = False
    return None


def leave(context, camera, display):
    """The view is leaving the hidden set's envelope: live, a pass during motion (it
    shows, it hides nothing new); otherwise show everything."""
    if context.scene is None or not context.scene.occ.live or SESSION.busy or SESSION.culler is None:
        SESSION.shown = None
        visibility.restore()
        return
    latency = (SESSION.last.ms if SESSION.last is not None else 100.0) / 1e3
    env = TRACKER.envelope(POLICY, latency, SESSION.culler.scene_size)
    try:
        SESSION.cull(context, camera, display, fresh=False, envelope=env, show_only=True)
        track(context)
        _state["dirty_at"] = None                     # our own pass's updates are not a change
    except OccError as e:
        print(f"occlusion culling: {e}")
        SESSION.shown = None
        visibility.restore()


def changed():
    """Something other than the view changed: re-cull once it rests (a listener of
    the change bus, :mod:`.handlers`)."""
    if _state["dirty_at"] is None:
        _state["dirty_at"] = time.perf_counter()


def _is_cut(passed, camera, display):
    """Whether the view jumped since the last pass at rest (``passed``: its camera and
    display size): the one definition of a cut (:func:`..core.camera.camera_cut`), or
    another display size.  After a cut the strategy starts fresh."""
    if passed is None:
        return True
    before, shown = passed
    size = SESSION.culler.scene_size if SESSION.culler is not None else 0.0
    return tuple(shown) != tuple(display) or camera_cut(before, camera, size)


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
    if settings != _state["settings"]:                # what may be hidden changed: a fresh pass
        if _state["settings"] is not None:
            changed()
        _state["settings"] = settings
    key = np.concatenate([camera.view.ravel(), camera.projection.ravel(), display])
    now = time.perf_counter()
    observe(camera)
    found = find_viewport(context) if scene.occ.source == "VIEWPORT" else None
    if found is not None and _view_changed(found[0].spaces.active) and SESSION.shown is not None:
        _state["dirty_at"] = now                      # it draws other objects now: a fresh pass next
        leave(context, camera, display)
    elif _unsafe(camera):                             # the redraw guard missed it: leave now
        leave(context, camera, display)
    if _state["last_view"] is None or not np.array_equal(key, _state["last_view"]):
        _state["last_view"], _state["changed_at"] = key, now
        return POLL_S
    rested = [t for t in (_state["changed_at"], _state["dirty_at"]) if t is not None]
    if rested and now - max(rested) >= DEBOUNCE_S:
        fresh = _state["dirty_at"] is not None or _is_cut(_state["passed"], camera, display)
        _state.update(changed_at=None, dirty_at=None)
        try:
            SESSION.cull(context, camera, display, fresh=fresh, envelope=AT_REST)
            track(context)
            _state["passed"] = (camera, display)
            _state["dirty_at"] = None                 # our own pass's updates are not a change
        except OccError as e:  # the user's to fix (an empty scene, a panoramic camera): show all, keep going
            print(f"occlusion culling: {e}")
            _state["passed"] = None
            SESSION.shown = None
            visibility.restore()
        except Exception:  # a timer must not raise: our bug, live mode stops and shows everything
            traceback.print_exc()
            print("occlusion culling stopped (details above)")
            SESSION.reset()
            visibility.restore()
            stop(context)
            return None
    return POLL_S


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
    return (("changed", changed), ("camera", guard_camera), ("loaded", after_load), ("undone", resync))


def register():
    for event, listener in _listens():
        bus.subscribe(event, listener)


def unregister():
    for event, listener in reversed(_listens()):
        bus.unsubscribe(event, listener)


def start(context):
    install()
    context.scene.occ.live = True
    _state.update(last_view=None, changed_at=time.perf_counter(), dirty_at=None, passed=None,
                  settings=settings_key(context.scene.occ))
    _ensure_timer()


def stop(context):
    context.scene.occ.live = False
    _drop_timer()
    _state.update(last_view=None, changed_at=None, dirty_at=None, passed=None)


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
    and the restored scene is culled again."""
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
    live pass that follows hides again)."""
    if SESSION.shown is None or SESSION.busy or not scene.occ.live or scene.occ.source != "CAMERA":
        return
    try:
        camera, _ = scene_camera(bpy.context, scene)
    except OccError:
        camera = None
    if camera is None:
        CAMERA_TRACKER.view = None
    else:
        CAMERA_TRACKER.observe(camera, time.perf_counter())
    if SESSION.shown is None:        # evaluating the camera ran this handler again, which showed all
        return
    centre, envelope = SESSION.shown
    if camera is None or not CAMERA_TRACKER.safe(POLICY, centre, envelope, camera):
        SESSION.shown = None
        visibility.restore()
