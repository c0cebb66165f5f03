"""Hiding and restoring, non-destructively, in bulk; the user owns every hide flag.

Two channels, one record each:

- **In one 3D view** (where a pass has a view: :func:`.cameras.hide_view`): the
  view's local-view bits (:mod:`.localview`), recorded in ``Object.occ_view_culled``.
  Nothing changes in any other view, window or scene; the objects stay evaluated.
- **Everywhere** (background mode, or the "Every View" setting): ``hide_viewport``,
  below.

The add-on hides everywhere with ``hide_viewport`` (the monitor icon) written by one
``foreach_set`` over ``bpy.data.objects`` and records what it hid in
``Object.occ_culled``.  The pair (``occ_culled``, ``hide_viewport``) is the
record: ``occ_culled`` set means "the add-on wrote hide_viewport = True here".

- An object the user shows (monitor icon, script) has ``occ_culled`` with
  ``hide_viewport`` off: the user touched it, it leaves the record
  (:func:`reconcile`, run by the depsgraph handler after every change, by every
  pass and by Restore).  A later hide by the user is then the user's, and
  Restore leaves it alone (the handler sees the show in between: every show is
  evaluated, so it is reported).
- The add-on never takes over an object the user hid in any way (eye,
  monitor, collection eye / monitor / exclude, view layer): such objects are
  not candidates (:mod:`.extract`), and one the add-on had hidden is given
  back: its ``hide_viewport`` is cleared, the user's own hide keeps it hidden.
- Restore (:func:`restore`) clears exactly the record.  Files are never saved
  with the add-on's hiding in them (:func:`lift` before save, :func:`reapply`
  after), and a file that carries a record (an older version, or a crash)
  is restored on load and when the add-on is enabled.

A bulk ``foreach_set`` skips RNA update callbacks.  Blender re-syncs its
per-view-layer bases only from an ordinary assignment, and an object shown
again must also be re-evaluated (it was not evaluated while hidden, so its
animation would stay at the frame it was hidden on): every object shown is
tagged (O(shown), cheap), and one ordinary assignment re-syncs the bases.
"""


import bpy
import numpy as np

from . import localview
from .identity import VIEW_RECORD, flags, objects, one_pass, store, uids

# Shown again: re-evaluate transform, geometry and animation at the current frame.
SHOW_TAG = {"OBJECT", "DATA", "TIME"}
# ... but an object a particle system instances: the dependency graph kept evaluating it
# while it was hidden (its instances need it), so nothing of it is stale, and a transform
# tag on it is what Blender 4.2 and 5.0 crash on after an emitter's delete and undo
# (../shared/repro/blender_hair_undo_two_layers.py): its data only.
INSTANCED_SHOW_TAG = {"DATA"}


def write(hide, record):
    """Set ``hide_viewport`` and ``occ_culled`` of every object (``(n,) bool`` each)
    in bulk; objects shown by this write are tagged for evaluation and the
    view layers' bases are re-synced once."""
    objs = bpy.data.objects
    old = flags("hide_viewport")
    hide = np.ascontiguousarray(hide, dtype=bool)
    changed = np.flatnonzero(old != hide)
    COUNT["changed"] += len(changed)
    if len(changed):
        objs.foreach_set("hide_viewport", hide)
    _set_record("occ_culled", flags("occ_culled"), np.asarray(record, dtype=bool))
    if not len(changed):
        return
    shown = changed[~hide[changed]]
    if len(shown):
        items = objs.values()                      # one list; ListBase indexing is O(i) per call
        instanced = {o.as_pointer() for o in particle_instanced()}
        for i in shown:                            # O(shown): a tag each, no re-sync each
            o = items[i]
            o.update_tag(refresh=INSTANCED_SHOW_TAG if o.as_pointer() in instanced else SHOW_TAG)
    first = objs[int(changed[0])]
    first.hide_viewport = bool(hide[changed[0]])   # the RNA update: bases re-synced, relations rebuilt


def particle_instanced() -> list:
    """Every object a particle system instances (its instance object, or its instance
    collection's objects): particle settings are few."""
    out = []
    for p in bpy.data.particles:
        if p.instance_object is not None:
            out.append(p.instance_object)
        if p.instance_collection is not None:
            out.extend(p.instance_collection.all_objects)
    return out


# the 3D view (SpaceView3D pointer) whose local-view bits the view record cleared
_view = {"pointer": None}


def hiding_view() -> int | None:
    """The 3D view (``SpaceView3D.as_pointer()``) the add-on hides in now; None: none, or everywhere."""
    return _view["pointer"]


def culled(collection=None):
    """``(n,) bool``: hidden by the add-on now, in either channel."""
    return flags("occ_culled", collection) | flags(VIEW_RECORD, collection)


def reconcile():
    """Drop from the record every object the user showed since the add-on hid it
    (the monitor icon; for the view channel, the view left local view: Numpad /, or
    it was closed); returns how many."""
    n = _reconcile_view()
    culled = flags("occ_culled")
    if not culled.any():
        return n
    touched = culled & ~flags("hide_viewport")
    if touched.any():
        store("occ_culled", culled & ~touched)
    return n + int(touched.sum())


def _view_space():
    """The 3D view the view record hides in, while it is in local view; else None."""
    found = localview.find(_view["pointer"]) if _view["pointer"] is not None else None
    return found[2] if found is not None and found[2].local_view is not None else None


def _reconcile_view():
    """With the view gone or out of local view, everything draws there: no record."""
    if _view["pointer"] is None or _view_space() is not None:
        return 0
    _view["pointer"] = None
    record = flags(VIEW_RECORD)
    if record.any():
        store(VIEW_RECORD, np.zeros(len(record), dtype=bool))
    return int(record.sum())


# objects whose hiding this session's writes changed (a pass reads the difference)
COUNT = {"changed": 0}


def _set_bits(space, mask, state):
    idx = np.flatnonzero(mask)
    if not len(idx):
        return
    items = objects()
    for i in idx:                                  # O(changed): Blender tags once per update
        items[i].local_view_set(space, state)
    COUNT["changed"] += len(idx)


def _set_record(prop, old, new):
    """Write record ``prop`` (``(n,) bool`` each): item by item where few changed (a
    bulk write of an add-on property costs about 1 us per object), else in bulk."""
    idx = np.flatnonzero(old != new)
    if len(idx) * 8 < len(new):
        store(prop, new, at=idx)
    elif len(idx):
        store(prop, new)


def apply(hide, view=None):
    """Make exactly ``hide`` (``(n,) bool`` over ``bpy.data.objects``) hidden by the
    add-on; every other object it hid comes back.  ``view``: ``(window, area)`` of the
    3D view to hide in (its local-view bits), None: everywhere (``hide_viewport``).
    Returns how many are hidden."""
    reconcile()
    hide = np.array(hide, dtype=bool)
    if view is None:
        _release_view(np.ones(len(hide), dtype=bool))
        localview.leave_all()
        culled = flags("occ_culled")
        hidden = flags("hide_viewport")
        want = hide & (culled | ~hidden)            # never take over a user's hide
        write(np.where(culled, False, hidden) | want, want)
        return int(want.sum())
    win, area = view
    space = area.spaces.active
    if _view["pointer"] not in (None, space.as_pointer()):
        _release_view(np.ones(len(hide), dtype=bool))   # the record moves to this view
    localview.leave_all(but=space)
    release_monitor = flags("occ_culled")
    if release_monitor.any():
        write(flags("hide_viewport") & ~release_monitor, np.zeros(len(hide), dtype=bool))
    if space.local_view is None:
        if not hide.any():
            return 0
        localview.enter(win, area)
        if space.local_view is None:               # no local view to be had: hide nothing
            return 0
    record = flags(VIEW_RECORD)
    change = record != hide
    if not localview.is_own(space):
        # in the user's local view: only its members are drawn there, only they are hidden
        # (``visible_get``: ``local_view_get`` can read a base Blender no longer draws)
        items, layer = objects(), win.view_layer
        for i in np.flatnonzero(change & hide):
            if not items[i].visible_get(view_layer=layer, viewport=space):
                hide[i] = change[i] = False
    _set_bits(space, change & hide, False)
    _set_bits(space, change & ~hide, True)
    _set_record(VIEW_RECORD, record, hide)
    _view["pointer"] = space.as_pointer() if hide.any() else _view["pointer"]
    return int(hide.sum())


def _release_view(give, leaving=False):
    """Give back the objects of ``give`` that the view record hides (``leaving``: the
    add-on's own local view ends right after); returns how many."""
    record = flags(VIEW_RECORD)
    give = record & give
    if not give.any():
        return 0
    space = _view_space()
    if space is not None and leaving and localview.is_own(space) and not (record & ~give).any():
        pass                                       # leaving the own local view draws everything
    elif space is not None:
        _set_bits(space, give, True)
    elif _view["pointer"] is None:
        # a record without its view (a file saved by a crash or an autosave): every
        # view in local view draws them
        for _, _, other in localview.spaces():
            if other.local_view is not None:
                _set_bits(other, give, True)
    _set_record(VIEW_RECORD, record, record & ~give)
    if not (record & ~give).any():
        _view["pointer"] = None
    return int(give.sum())


def release(mask, leaving=False):
    """Show again the objects of ``mask`` (``(n,) bool``) that the add-on hid; returns how many."""
    reconcile()
    mask = np.asarray(mask, dtype=bool)
    n = _release_view(mask, leaving)
    culled = flags("occ_culled")
    give = culled & mask
    if not give.any():
        return n
    write(flags("hide_viewport") & ~give, culled & ~give)
    return n + int(give.sum())


def restore():
    """Show again every object the add-on hid (and only those), and end the add-on's
    own local view; returns how many."""
    with one_pass():
        n = release(np.ones(len(bpy.data.objects), dtype=bool), leaving=True)
    localview.leave_all()
    return n


def after_undo():
    """Undo and redo bring the record and the bits back with the data, not the views:
    an own local view holds every object but those its record hides; a record whose
    view is gone, out of local view or given back since (a Restore, then an undo to
    data of before it) is dropped, its objects' bits set again in every view in local
    view (the user's own among them: the data brought back their cleared bits)."""
    _reconcile_view()
    record = flags(VIEW_RECORD)
    localview.resync(uids()[record] if _view["pointer"] is not None else uids()[:0])
    if _view["pointer"] is None and record.any():
        _release_view(record)


def after_load():
    """A file opens with everything the add-on hid shown again (files saved by older
    versions, a crash or an autosave)."""
    _view["pointer"] = None
    localview.forget()
    restore()


# --- files are saved without the add-on's hiding ------------------------------------
_lifted = {"uids": None, "view": None}


def lift():
    """Before a save: show what the add-on hid and end its own local view, remembering
    both (session ids, the view)."""
    record = culled()
    _lifted["uids"] = uids()[record] if record.any() else None
    found = localview.find(_view["pointer"]) if _view["pointer"] is not None else None
    _lifted["view"] = (found[0], found[1]) if found is not None and flags(VIEW_RECORD).any() else None
    if record.any():
        restore()
    localview.leave_all()      # hiding nothing, it is not saved either (unknown to whoever opens the file)


def reapply():
    """After a save: hide again what :func:`lift` showed, where the user has not
    hidden it since (nothing can change in between but the file on disk)."""
    lifted, view = _lifted["uids"], _lifted["view"]
    _lifted.update(uids=None, view=None)
    if lifted is None:
        return
    apply(np.isin(uids(), lifted), view)
