"""What Blender draws now: what a 3D view draws, in bulk (:func:`drawn`), and what it
will draw of an object the add-on hid (:func:`view_shows`, :func:`filters_geometry`);
what the user's own flags show (:func:`shown_by_collections`, :func:`user_shown`); what
the render leaves out (:func:`left_out_of_render`); and what Blender draws that the engine
does not hold (:func:`bystanders`)."""

from enum import Enum

import bpy
import numpy as np

from . import identity
from .identity import ident
from .kinds import GEOMETRY_TYPES, RENDER_KEYS, is_collection_instance


def shown_by_collections(view_layer):
    """``(m,) int64`` sorted session ids of the objects in the collections the view
    layer shows (not excluded, eye and monitor on, all the way up), in bulk."""
    ids = []
    stack = [(view_layer.layer_collection, True)]
    while stack:                                   # collections: a handful
        lc, ok = stack.pop()
        ok = ok and not lc.exclude and not lc.hide_viewport and not lc.collection.hide_viewport
        if ok:
            ids.append(identity.uids(lc.collection.objects))
        stack.extend((c, ok) for c in lc.children)
    return np.unique(np.concatenate(ids)) if ids else np.zeros(0, dtype=np.int64)


def rendered_by_collections(view_layer) -> np.ndarray:
    """Sorted identities of the objects the view layer renders to the camera by their
    collections: in a collection not excluded, not indirect only, not hidden from the
    render, and its parents neither."""
    found = []
    stack = [view_layer.layer_collection]
    while stack:
        lc = stack.pop()
        c = lc.collection
        if lc.exclude or getattr(lc, "indirect_only", False) or getattr(c, "hide_render", False):
            continue
        found.append(identity.uids(c.objects))
        stack.extend(lc.children)
    return np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=np.int64)


def hidden_by_own_keys(obj) -> bool:
    """Whether ``obj``'s render hide is the add-on's (Apply to Render's keys, :mod:`.render_keys`)."""
    ad = obj.animation_data
    return ad is not None and ad.action is not None and ad.action.get(RENDER_KEYS) is not None


def left_out_of_render(view_layer, uids: np.ndarray) -> np.ndarray:
    """``(k,) bool``: which of ``uids`` the render leaves out though a view may draw them:
    hidden from the render by their own flag (not the add-on's keys) or in no collection
    the view layer renders.  In bulk but for the objects hidden from the render."""
    off = identity.flags("hide_render")
    at = np.flatnonzero(off)
    if len(at):
        items = bpy.data.objects.values()
        off[[i for i in at.tolist() if hidden_by_own_keys(items[i])]] = False
    return np.isin(uids, identity.uids()[off]) | ~np.isin(uids, rendered_by_collections(view_layer))


def user_shown(obj, view_layer, shown):
    """Whether Blender would draw ``obj`` if the add-on had not hidden it: the
    user's eye, its collections' eye, monitor and exclude (``shown``: see
    :func:`shown_by_collections`), the view layer."""
    uid = ident(obj)
    k = np.searchsorted(shown, uid)
    return k < len(shown) and shown[k] == uid and not obj.hide_get(view_layer=view_layer)


DRAWN_TYPES = GEOMETRY_TYPES | {"POINTCLOUD", "VOLUME", "GREASEPENCIL", "GPENCIL", "CURVES"}

# The object-type filters of a 3D view (``SpaceView3D.show_object_viewport_*``) of the types that take part
TYPE_FILTERS = {"MESH": "show_object_viewport_mesh", "CURVE": "show_object_viewport_curve",
                "SURFACE": "show_object_viewport_surf", "META": "show_object_viewport_meta",
                "FONT": "show_object_viewport_font", "EMPTY": "show_object_viewport_empty"}


def view_shows(obj, space, stale: bool = True) -> bool:
    """Whether 3D view ``space`` draws ``obj``, which the add-on hid, once it is shown
    again, as far as that can be told while it is hidden: its object-type filter.
    Hidden everywhere (``stale``: not evaluated), in local view or with local
    collections it cannot (Blender brings an object's membership up to date only while
    it is drawn: ``visible_in_viewport_get`` and ``local_view_get`` read stale bits):
    False, so it is given back and evaluated.  Hidden in a view's local view by the
    add-on, it was in that local view when hidden, and nothing but leaving the local
    view (which ends the hiding) changes that."""
    if space.use_local_collections or (stale and space.local_view is not None):
        return False
    return getattr(space, TYPE_FILTERS.get(obj.type, ""), True)


def filters_geometry(space) -> bool:
    """Whether 3D view ``space`` filters out a type that takes part.  A collection
    instance is drawn by its members' types, which the instancer's own visibility
    does not tell: in such a view it is no candidate (conservative: it neither
    occludes nor is hidden)."""
    return space is not None and not all(getattr(space, TYPE_FILTERS[t]) for t in GEOMETRY_TYPES)


def bystanders(view_layer, held: np.ndarray) -> list:
    """Objects Blender draws now that the engine does not hold (``held``: the
    engine's objects' session ids, ``(k,) int64``): wire and bounds display, point
    clouds, volumes, grease pencil, hair, vertex-instanced children, NaN values.
    Never culled, so counted visible by analyze.  The held ones are told apart in
    bulk (one ``foreach_get``); only the others are looked at one by one."""
    uids, items = identity.layer_objects(view_layer)    # (a list: indexing the collection is O(i))
    rest = np.flatnonzero(~np.isin(uids, held))
    if not len(rest):
        return []
    return [o for o in (items[i] for i in rest)
            if (o.type in DRAWN_TYPES or is_collection_instance(o)) and o.visible_get()]


class NoView(Enum):
    """:func:`drawn`'s ``space`` for no 3D view at all: the view layer's own visibility."""

    BASE = "base"


def base_shown(view_layer) -> list | None:
    """What ``view_layer`` draws with no view (its eye, collection and monitor flags), as
    one list (``context.visible_objects`` outside any 3D view); None where the context
    cannot tell it (another view layer, or no override without a view)."""
    context = bpy.context
    if context.view_layer != view_layer:
        return None
    if context.area is None:
        return context.visible_objects
    try:
        with context.temp_override(area=None, region=None):
            return bpy.context.visible_objects
    except (TypeError, RuntimeError):
        return None


def drawn(view_layer, uids_all: np.ndarray, space=None) -> np.ndarray:
    """``(n,) bool`` over ``view_layer.objects``: what Blender draws in 3D view ``space``
    (None: the context's 3D view, if any; :attr:`NoView.BASE`: no view, the view layer's eye,
    collection and monitor flags), as ``visible_get(viewport=space)`` tells one object at
    a time, in bulk: ``context.visible_objects`` in that view's context (one list, a
    fraction of a ``visible_get`` per object)."""
    context = bpy.context
    found = None
    if space is NoView.BASE:                         # no view: the view layer's own visibility
        shown = base_shown(view_layer)
        if shown is None:                            # one by one: the eye, collections, monitor
            ids = shown_by_collections(view_layer)
            return np.fromiter((user_shown(o, view_layer, ids) and not o.hide_viewport
                                for o in view_layer.objects), dtype=bool, count=len(uids_all))
        ids = identity.idents(shown)
        return np.isin(uids_all, ids)
    if space is not None:
        found = next(((w, a) for w in context.window_manager.windows for a in w.screen.areas
                      if a.spaces.active == space), None)
        if found is None or found[0].view_layer != view_layer:   # not a view of this layer's window
            return np.fromiter((o.visible_get(viewport=space) for o in view_layer.objects), dtype=bool,
                               count=len(uids_all))
    if found is None:
        if context.view_layer != view_layer:
            return np.fromiter((o.visible_get() for o in view_layer.objects), dtype=bool, count=len(uids_all))
        shown = context.visible_objects
    else:
        win, area = found
        region = next((r for r in area.regions if r.type == "WINDOW"), None)
        with context.temp_override(window=win, area=area, region=region):
            shown = bpy.context.visible_objects
    ids = identity.idents(shown)
    return np.isin(uids_all, ids)
