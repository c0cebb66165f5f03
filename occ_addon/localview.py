"""Hiding in one 3D view only: Blender's local-view bits.

Blender draws an object in a 3D view that is in local view only where the
object's base carries that view's bit (``Object.local_view_set``).  A bit changed
costs Blender one base-flags update (no dependency-graph relations rebuild,
unlike ``hide_viewport``) and changes nothing drawn in any other view, window or
scene: the add-on hides there (:mod:`.visibility`, the view channel).

A view the user put in local view (Numpad /) is used as it is: the add-on clears
the bits of what it culls and sets them back.  A view that is not in local view is
put in the add-on's *own* local view, holding every object of the window's view
layer, so it draws what it drew before:

- entering never moves the view (``frame_selected=False``) and leaves the user's
  selection as it was; leaving puts the view back where it is now (Blender's
  local view would go back to where it was on entering);
- an object that joins the view layer while it is in force (added, linked,
  appended, its collection included again) gets the bit at once
  (:func:`adopt`, from the depsgraph handler), as do all objects after an undo
  (:func:`resync`) or in another view layer shown in that window;
- it ends with the add-on's hiding (Restore, live off, before a save): the view
  is as the user left it, no local view.

The add-on's own local view is known by its ``SpaceView3D`` (``as_pointer``):
Blender's user interface survives undo, not a file load, and a file is never
saved with it (:func:`.visibility.lift`).
"""

from dataclasses import dataclass

import bpy
import numpy as np

from . import bus
from .identity import after_update, uids
from .worker import quiet


@dataclass
class OwnView:
    """One of the add-on's own local views: its window's view layer (by name) and the
    session ids of that layer's objects that hold the view's bit ``(k,) int64``, sorted."""

    layer: str
    uids: np.ndarray


_own: dict[int, OwnView] = {}     # SpaceView3D pointer -> its OwnView


def spaces():
    """Every ``(window, area, space)`` of a 3D view in the open windows."""
    wm = bpy.context.window_manager
    for win in (wm.windows if wm is not None else ()):
        for area in win.screen.areas:
            if area.type == "VIEW_3D":
                yield win, area, area.spaces.active


def find(pointer: int):
    """``(window, area, space)`` of the 3D view whose space is ``pointer``, or None."""
    return next(((w, a, s) for w, a, s in spaces() if s.as_pointer() == pointer), None)


def is_own(space) -> bool:
    return space is not None and space.as_pointer() in _own


def user_local(space) -> bool:
    """Whether ``space`` is in a local view of the user's (not the add-on's own)."""
    return space.local_view is not None and not is_own(space)


def _region(area):
    return next(r for r in area.regions if r.type == "WINDOW")


def _toggle(win, area) -> None:
    """Blender's local-view toggle in ``area``, without the view-layer updates ``bpy.ops``
    makes before and after every call up to Blender 5.1 (two full base updates at scale:
    the one the pass makes after hiding covers them); 5.2's operators are called as they
    are (its ``bpy.ops`` has no Python-side call left to go around)."""
    quiet()                                          # no engine thread runs while the operator does
    try:
        _call_toggle(win, area)
    finally:
        after_update()                               # handlers may have run inside it


def _call_toggle(win, area) -> None:
    with bpy.context.temp_override(window=win, area=area, region=_region(area)):
        op, kw = bpy.ops.view3d.localview, {"frame_selected": False}
        try:
            from _bpy import ops
        except ImportError:
            ops = None
        if ops is None or not hasattr(ops, "call") or not hasattr(op, "idname_py"):
            op(**kw)                                 # Blender 5.2+: operators are C callables
            return
        if bpy.app.version >= (4, 0, 0):
            ops.call(op.idname_py(), kw)             # (idname, properties)
        else:
            ops.call(op.idname_py(), None, kw)       # (idname, context override, properties)


def _layer_uids(layer):
    return np.sort(uids(layer.objects))


def _set_all(layer, space, state=True, only=None):
    """Set ``space``'s bit of the objects of ``layer`` (``only``: ``(n,) bool`` over
    ``layer.objects``) to ``state``: one call each, no update each (Blender tags once)."""
    items = layer.objects.values()
    for i in (range(len(items)) if only is None else np.flatnonzero(only)):
        items[i].local_view_set(space, state)


def _draws_selected(space, layer) -> bool:
    """Whether 3D view ``space`` draws an object selected in ``layer``."""
    return any(o.visible_get(view_layer=layer, viewport=space) for o in layer.objects.selected)


def pick(win, area):
    """Blender enters local view with the selection: where the view draws no selected
    object, select one it draws (for the entry only) and return it; None where one is
    selected already, or nothing is drawn.  The caller deselects it after the entry."""
    space, layer = area.spaces.active, win.view_layer
    if _draws_selected(space, layer):
        return None
    picked = next((o for o in layer.objects if o.visible_get(view_layer=layer, viewport=space)), None)
    if picked is not None:
        picked.select_set(True, view_layer=layer)
    return picked


def enter(win, area) -> None:
    """Put ``area``'s 3D view in the add-on's own local view holding every object of
    the window's view layer, the view unmoved and the selection unchanged (an object
    selected for it by :func:`pick` beforehand is the caller's to deselect)."""
    space = area.spaces.active
    if space.local_view is not None:
        return
    layer = win.view_layer
    picked = pick(win, area)
    if picked is None and not _draws_selected(space, layer):
        return                                       # nothing drawn: nothing to hide either
    try:
        _toggle(win, area)
    finally:
        if picked is not None:
            picked.select_set(False, view_layer=layer)
    if space.local_view is None:                     # Blender has no local view left (16 at most)
        return
    _own[space.as_pointer()] = OwnView(layer.name, _layer_uids(layer))
    _set_all(layer, space)


# the view of a 3D region, kept across leaving local view
_VIEW_PROPS = ("view_location", "view_rotation", "view_distance", "view_perspective",
               "view_camera_zoom", "view_camera_offset")


def leave(win, area) -> None:
    """End the add-on's own local view of ``area``: every object is drawn again and
    the view stays where it is (Blender would go back to where it was on entering)."""
    space = area.spaces.active
    _own.pop(space.as_pointer(), None)
    if space.local_view is None:
        return
    regions = [space.region_3d, *space.region_quadviews]
    views = [(r, {p: _copy(getattr(r, p)) for p in _VIEW_PROPS}) for r in regions if r is not None]
    camera = space.camera
    prefs = bpy.context.preferences
    smooth, dirty = prefs.view.smooth_view, prefs.is_dirty
    prefs.view.smooth_view = 0                       # no animated move back
    try:
        _toggle(win, area)
    finally:
        prefs.view.smooth_view = smooth
        prefs.is_dirty = dirty
        for rv3d, saved in views:
            for p, v in saved.items():
                setattr(rv3d, p, v)
        space.camera = camera
        if space.local_view is not None:             # still in it (the call failed): draw everything
            _set_all(win.view_layer, space)


def _copy(v):
    return v.copy() if hasattr(v, "copy") else v


def leave_all(but=None) -> int:
    """End every own local view (Restore, before a save, the add-on goes away), ``but``
    that of this space; returns how many."""
    n = 0
    for pointer in list(_own):
        if but is not None and pointer == but.as_pointer():
            continue
        found = find(pointer)
        if found is None:
            _own.pop(pointer, None)
            continue
        leave(found[0], found[1])
        n += 1
    return n


def layer_switched() -> bool:
    """Whether a window with an own local view shows another view layer than when its
    bits were last set (its bases there carry none yet)."""
    for pointer, own in _own.items():
        found = find(pointer)
        if found is not None and found[0].view_layer.name != own.layer:
            return True
    return False


def on_window_change(*_args) -> None:
    """A window shows another view layer or scene (a message-bus subscription, GUI):
    before it is drawn, its own local view holds every object of it."""
    if _own and layer_switched():
        adopt()
    bus.emit("window")


_owner = object()


def subscribe() -> None:
    """The message bus tells a window's view-layer and scene switches (GUI only)."""
    for prop in ("view_layer", "scene"):
        bpy.msgbus.subscribe_rna(key=(bpy.types.Window, prop), owner=_owner, args=(), notify=on_window_change)


def unsubscribe() -> None:
    bpy.msgbus.clear_by_owner(_owner)


def adopt() -> None:
    """Objects that joined a view layer shown in an own local view get its bit (the
    depsgraph handler, after every change): nothing new is hidden there."""
    for pointer, own in list(_own.items()):
        found = find(pointer)
        if found is None or found[2].local_view is None:
            _own.pop(pointer, None)                  # closed, or left by the user (Numpad /)
            continue
        win, _, space = found
        layer = win.view_layer
        now = _layer_uids(layer)
        if layer.name != own.layer:
            fresh = np.ones(len(now), dtype=bool)
        else:
            fresh = ~np.isin(now, own.uids, assume_unique=True)
        if fresh.any():
            ids = uids(layer.objects)
            _set_all(layer, space, True, np.isin(ids, now[fresh]))
        own.layer, own.uids = layer.name, now


def resync(culled) -> None:
    """After an undo or redo (the bits come back with the data, the view does not):
    every object of an own local view holds its bit but those ``culled`` (``(m,)
    int64`` session ids the restored record hides there)."""
    for pointer, own in list(_own.items()):
        found = find(pointer)
        if found is None or found[2].local_view is None:
            _own.pop(pointer, None)
            continue
        win, _, space = found
        layer = win.view_layer
        ids = uids(layer.objects)
        keep = np.isin(ids, culled)
        _set_all(layer, space, True, ~keep)
        _set_all(layer, space, False, keep)
        own.layer, own.uids = layer.name, np.sort(ids)


def forget() -> None:
    """A file was loaded: its views are new (no own local view is saved in a file)."""
    _own.clear()
