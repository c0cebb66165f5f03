"""Live culling: a timer polls the viewport's view matrix (navigation fires no
depsgraph update) and re-culls, debounced, when it changed.  GUI only."""

import time
import traceback

import bpy
import numpy as np

from ..core import OccError
from .session import SESSION, camera_for

POLL_S = 0.1          # timer period
DEBOUNCE_S = 0.15     # the view must rest this long before a pass

_state = {"last_view": None, "changed_at": None, "scene": None}


def _tick():
    context = bpy.context
    scene = _state["scene"]
    if scene is None or not scene.occ.live:
        return None                                   # stops the timer
    try:
        camera, display = camera_for(context)
    except OccError:
        return POLL_S
    key = np.concatenate([camera.view.ravel(), camera.projection.ravel(), display])
    now = time.perf_counter()
    if _state["last_view"] is None or not np.array_equal(key, _state["last_view"]):
        _state["last_view"], _state["changed_at"] = key, now
        return POLL_S
    if _state["changed_at"] is not None and now - _state["changed_at"] >= DEBOUNCE_S:
        _state["changed_at"] = None
        try:
            SESSION.cull(context, camera, display)
        except Exception as e:  # a timer must not raise; live mode stops instead
            if not isinstance(e, OccError):
                traceback.print_exc()
                SESSION.reset()
            print(f"occlusion culling stopped: {e}")
            scene.occ.live = False
            return None
    return POLL_S


def start(context):
    from . import overlay
    overlay.install()
    context.scene.occ.live = True
    _state.update(last_view=None, changed_at=time.perf_counter(), scene=context.scene)
    if not bpy.app.timers.is_registered(_tick):
        bpy.app.timers.register(_tick, first_interval=0.0)


def stop(context):
    context.scene.occ.live = False
    if bpy.app.timers.is_registered(_tick):
        bpy.app.timers.unregister(_tick)
    _state.update(last_view=None, changed_at=None, scene=None)
