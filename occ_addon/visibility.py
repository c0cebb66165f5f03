"""Hiding and restoring, non-destructively, in bulk; the user owns every hide flag.

The add-on hides with ``hide_viewport`` (the monitor icon) written by one
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

# Shown again: re-evaluate transform, geometry and animation at the current frame.
SHOW_TAG = {"OBJECT", "DATA", "TIME"}


def flags(prop, collection=None):
    """``(n,) bool`` of a boolean property over ``collection`` (default ``bpy.data.objects``)."""
    objs = bpy.data.objects if collection is None else collection
    out = np.zeros(len(objs), dtype=bool)
    objs.foreach_get(prop, out)
    return out


# Blender 3.5+ gives every datablock a session id (kept by renames, never reused in a
# session); Blender 3.4 has none: there the address stands in (reused only after a
# deletion, and a new object is always reported to the depsgraph handler as changed).
HAS_SESSION_UID = "session_uid" in bpy.types.ID.bl_rna.properties


def ident(idblock):
    """The identity of a datablock for this Blender session."""
    return idblock.session_uid if HAS_SESSION_UID else idblock.as_pointer()


def uids(collection=None):
    """``(n,) int64`` identities (:func:`ident`) over ``collection`` (default ``bpy.data.objects``)."""
    objs = bpy.data.objects if collection is None else collection
    if not HAS_SESSION_UID:
        return np.fromiter((o.as_pointer() for o in objs), dtype=np.int64, count=len(objs))
    out = np.zeros(len(objs), dtype=np.int64)
    objs.foreach_get("session_uid", out)
    return out


def write(hide, record):
    """Set ``hide_viewport`` and ``occ_culled`` of every object (``(n,) bool`` each)
    in bulk; objects shown by this write are tagged for evaluation and the
    view layers' bases are re-synced once."""
    objs = bpy.data.objects
    old = flags("hide_viewport")
    hide = np.ascontiguousarray(hide, dtype=bool)
    changed = np.flatnonzero(old != hide)
    if len(changed):
        objs.foreach_set("hide_viewport", hide)
    objs.foreach_set("occ_culled", np.ascontiguousarray(record, dtype=bool))
    if not len(changed):
        return
    shown = changed[~hide[changed]]
    if len(shown):
        items = objs.values()                      # one list; ListBase indexing is O(i) per call
        for i in shown:                            # O(shown): a tag each, no re-sync each
            items[i].update_tag(refresh=SHOW_TAG)
    first = objs[int(changed[0])]
    first.hide_viewport = bool(hide[changed[0]])   # the RNA update: bases re-synced, relations rebuilt


def reconcile():
    """Drop from the record every object the user showed since the add-on hid it;
    returns how many."""
    culled = flags("occ_culled")
    if not culled.any():
        return 0
    touched = culled & ~flags("hide_viewport")
    if touched.any():
        bpy.data.objects.foreach_set("occ_culled", culled & ~touched)
    return int(touched.sum())


def apply(hide):
    """Make exactly ``hide`` (``(n,) bool`` over ``bpy.data.objects``) hidden by the
    add-on; every other object it hid comes back.  Returns how many are hidden."""
    reconcile()
    culled = flags("occ_culled")
    hidden = flags("hide_viewport")
    want = np.asarray(hide, dtype=bool) & (culled | ~hidden)   # never take over a user's hide
    write(np.where(culled, False, hidden) | want, want)
    return int(want.sum())


def release(mask):
    """Show again the objects of ``mask`` (``(n,) bool``) that the add-on hid; returns how many."""
    reconcile()
    culled = flags("occ_culled")
    give = culled & np.asarray(mask, dtype=bool)
    if not give.any():
        return 0
    write(flags("hide_viewport") & ~give, culled & ~give)
    return int(give.sum())


def restore():
    """Show again every object the add-on hid (and only those); returns how many."""
    return release(np.ones(len(bpy.data.objects), dtype=bool))


# --- files are saved without the add-on's hiding ------------------------------------
_lifted = {"uids": None}


def lift():
    """Before a save: show what the add-on hid, remembering it (session ids)."""
    culled = flags("occ_culled")
    _lifted["uids"] = uids()[culled] if culled.any() else None
    if culled.any():
        restore()


def reapply():
    """After a save: hide again what :func:`lift` showed, where the user has not
    hidden it since (nothing can change in between but the file on disk)."""
    lifted, _lifted["uids"] = _lifted["uids"], None
    if lifted is None:
        return
    apply(np.isin(uids(), lifted))
