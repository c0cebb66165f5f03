"""Live culling: a timer re-culls, debounced, after every change that can change
what is visible: the view moved (polled: navigation fires no depsgraph update),
or anything else changed (the depsgraph and frame-change handlers, "never
cull" and the exclusion collection report it, see :func:`changed`).  GUI only.

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
from . import visibility
from .session import LISTENERS, SESSION, camera_for

POLL_S = 0.1          # timer period
DEBOUNCE_S = 0.15     # the view (or the scene) must rest this long before a pass
CUT_DEG = 10.0        # a view turned further than this between passes is a cut: the strategy starts fresh
CUT_MOVE = 0.05       # and so is one moved further than this fraction of the scene's size

_state = {"last_view": None, "changed_at": None, "dirty_at": None, "passed_view": None}


def changed():
    """Something other than the view changed: re-cull once it rests."""
    if _state["dirty_at"] is None:
        _state["dirty_at"] = time.perf_counter()


LISTENERS.append(changed)


def _eye(view):
    return -view[:3, :3].T @ view[:3, 3]


def _is_cut(old, new):
    """Whether the view turned more than CUT_DEG, moved more than CUT_MOVE of the
    scene's size, or the projection or display size changed."""
    if old is None:
        return True
    if not np.array_equal(old[16:], new[16:]):
        return True
    a, b = old[:16].reshape(4, 4), new[:16].reshape(4, 4)
    r = a[:3, :3].T @ b[:3, :3]
    cos = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    size = SESSION.culler.scene_size if SESSION.culler is not None else 0.0
    return bool(np.degrees(np.arccos(cos)) > CUT_DEG or np.linalg.norm(_eye(a) - _eye(b)) > CUT_MOVE * size)


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
    key = np.concatenate([camera.view.ravel(), camera.projection.ravel(), display])
    now = time.perf_counter()
    if _state["last_view"] is None or not np.array_equal(key, _state["last_view"]):
        _state["last_view"], _state["changed_at"] = key, now
        return POLL_S
    rested = [t for t in (_state["changed_at"], _state["dirty_at"]) if t is not None]
    if rested and now - max(rested) >= DEBOUNCE_S:
        fresh = _state["dirty_at"] is not None or _is_cut(_state["passed_view"], key)
        _state.update(changed_at=None, dirty_at=None)
        try:
            SESSION.cull(context, camera, display, fresh=fresh)
            _state["passed_view"] = key
            _state["dirty_at"] = None                 # our own pass's updates are not a change
        except OccError as e:  # the user's to fix (an empty scene, a panoramic camera): show all, keep going
            print(f"occlusion culling: {e}")
            _state["passed_view"] = None
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


def start(context):
    from . import overlay
    overlay.install()
    context.scene.occ.live = True
    _state.update(last_view=None, changed_at=time.perf_counter(), dirty_at=None, passed_view=None)
    _ensure_timer()


def stop(context):
    context.scene.occ.live = False
    _drop_timer()
    _state.update(last_view=None, changed_at=None, dirty_at=None, passed_view=None)


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
