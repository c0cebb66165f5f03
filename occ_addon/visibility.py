"""Hiding and restoring, non-destructively, in bulk.

The add-on hides with ``hide_viewport`` set through one ``foreach_set`` over
``bpy.data.objects`` (O(n) in C, no per-object ``hide_set`` loop, which costs
O(n) per call) and records every object it hid in ``Object.occ_culled``, saved
in the .blend.  It never touches an object the user hid (eye or monitor), an
excluded one, or one marked "never cull"; restoring clears exactly its record.
Local-view bits would leave even ``hide_viewport`` alone, but they exist only
while a viewport is in local view and never in background mode, where the
same operators must work.
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


def excluded_names(settings):
    """Names of the objects the user protected from hiding."""
    names = {o.name for o in bpy.data.objects if o.occ_never_cull}
    coll = settings.exclude_collection
    if coll is not None:
        objs = coll.all_objects if settings.exclude_children else coll.objects
        names.update(o.name for o in objs)
    return names


def apply(hide_names):
    """Make exactly ``hide_names`` (minus protected ones) hidden by the add-on.

    Objects the add-on hid before and that are not in ``hide_names`` come back.
    Returns the number of objects hidden now.
    """
    objs = bpy.data.objects
    culled = _flags("occ_culled")
    hidden = _flags("hide_viewport")
    want = np.zeros(len(objs), dtype=bool)
    if hide_names:
        lookup = {name: i for i, name in enumerate(objs.keys())}
        idx = [lookup[n] for n in hide_names if n in lookup]
        want[idx] = True
    # never take over an object the user hid: only ours or currently shown ones
    want &= culled | ~hidden
    hidden = np.where(culled, False, hidden) | want
    _set("hide_viewport", hidden)
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
