"""Hiding and restoring, non-destructively, in bulk.

The add-on hides with ``hide_viewport`` set through one ``foreach_set`` over
``bpy.data.objects`` (O(n) in C, no per-object ``hide_set`` loop, which costs
O(n) per call) and records every object it hid in ``Object.occ_culled``, saved
in the .blend.  It never touches an object the user hid (eye or monitor), an
excluded one, or one marked "never cull"; restoring clears exactly its record.
Local-view bits would leave even ``hide_viewport`` alone, but they exist only
while a viewport is in local view and never in background mode, where the
same operators must work.

Blender neither evaluates nor reports (depsgraph updates) an object while it is
hidden, so an edit made by script to an object the add-on hides is read only
once the object is shown again (``occ.restore``, or a pass that finds it
visible by its last extracted shape).
"""

import bpy
import numpy as np


def _flags(prop):
    objs = bpy.data.objects
    out = np.zeros(len(objs), dtype=bool)
    objs.foreach_get(prop, out)
    return out


def _set(prop, values):
    objs = bpy.data.objects
    objs.foreach_set(prop, np.ascontiguousarray(values, dtype=bool))
    if prop == "hide_viewport" and len(objs):
        # foreach_set skips RNA update callbacks; one ordinary assignment fires the
        # hide update once, which re-syncs every base of every view layer (O(n), once).
        first = objs[0]
        first.hide_viewport = bool(values[0])


def protected(settings, names):
    """``(k,) bool`` over ``names``: objects the user protected from hiding (the
    exclusion collection, with its children when asked, and "never cull")."""
    objs = bpy.data.objects
    flagged = np.flatnonzero(_flags("occ_never_cull"))
    keep = set()
    if len(flagged):
        all_names = objs.keys()
        keep.update(all_names[i] for i in flagged)
    coll = settings.exclude_collection
    if coll is not None:
        keep.update(o.name for o in (coll.all_objects if settings.exclude_children else coll.objects))
    if not keep:
        return np.zeros(len(names), dtype=bool)
    return np.fromiter((n in keep for n in names), dtype=bool, count=len(names))


def apply(hide_names):
    """Make exactly ``hide_names`` (minus protected ones) hidden by the add-on.

    Objects the add-on hid before and that are not in ``hide_names`` come back.
    Returns the number of objects hidden now.
    """
    objs = bpy.data.objects
    culled = _flags("occ_culled")
    hidden = _flags("hide_viewport")
    want = np.zeros(len(objs), dtype=bool)
    if len(hide_names):
        lookup = {name: i for i, name in enumerate(objs.keys())}
        idx = [lookup[n] for n in hide_names if n in lookup]
        want[idx] = True
    # never take over an object the user hid: only ours or currently shown ones
    want &= culled | ~hidden
    _set("hide_viewport", np.where(culled, False, hidden) | want)
    _set("occ_culled", want)
    return int(want.sum())


def restore():
    """Show again every object the add-on hid; returns how many."""
    culled = _flags("occ_culled")
    if not culled.any():
        return 0
    _set("hide_viewport", _flags("hide_viewport") & ~culled)
    _set("occ_culled", np.zeros_like(culled))
    return int(culled.sum())
