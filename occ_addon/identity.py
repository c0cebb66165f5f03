"""Who an object is, and the add-on's records over every object, read in bulk.

An object's identity for this Blender session is its ``session_uid`` (Blender 3.5+:
kept by renames, never reused in a session), or on Blender 3.4 its address.  The
add-on's per-object records (``Object.occ_culled``, ``Object.occ_view_culled``), the
identities of ``bpy.data.objects`` and its length are read once a pass
(:func:`one_pass`): inside an operator's call no user action, undo or file load runs,
every write of a record is :func:`store`'s, which keeps the memo current, and the
length is read again after each update (:func:`evaluate`).  The records are also kept
from pass to pass (:func:`flags`), over the same identities in the same order: only the
add-on writes them, and what replaces them (undo, redo, a file load) makes the session
forget them (:func:`forget`).  This module imports nothing of the add-on: every other
module may use it.
"""

import contextlib
from operator import attrgetter, itemgetter

import bpy
import numpy as np

# The add-on's records (a property of the add-on's own costs Blender about 0.7 us an
# object to read in bulk: 35 ms at 50,000 objects, and a pass asks several times).
VIEW_RECORD = "occ_view_culled"
RECORDS = ("occ_culled", VIEW_RECORD)
# Within one pass (:func:`one_pass`) each record over ``bpy.data.objects``, and the
# objects' identities (:func:`uids`), are read once: inside an operator's call no user
# action, undo or file load runs, and every write of a record is this module's
# (:func:`store`), which keeps the memo current.
_memo: dict | None = None
# Across passes, each record as :func:`store` last wrote it or :func:`flags` last read it,
# with the identities it was over (Blender 3.5+: session ids are never reused, so the
# same array of them is the same objects in the same order).  No script or Blender
# operation writes an add-on's record but the add-on (duplicates and appended objects
# are new identities); undo, redo and file loads replace every object's data: the
# session forgets the kept records then (:meth:`.session.Session.reset`).  Saves two
# bulk reads of 24 ms each on every pass at 50,000 objects.
_kept: dict[str, tuple[np.ndarray, np.ndarray]] = {}


@contextlib.contextmanager
def one_pass():
    """Read each record once in the block (a pass, a Restore); nested blocks share it."""
    global _memo
    outer = _memo
    if outer is None:
        _memo = {}
    try:
        yield
    finally:
        if outer is None:
            _memo = None


def count() -> int:
    """``len(bpy.data.objects)``: a walk of Blender's list (about 1 ms at 50,000 objects),
    made once within :func:`one_pass` and again after each :func:`evaluate` in it (only
    handlers, inside an update, can add or remove an object during a pass); a memo whose
    length differs is read again."""
    if _memo is None:
        return len(bpy.data.objects)
    n = _memo.get("n")
    if n is None:
        n = _memo["n"] = len(bpy.data.objects)
    return n


def objects() -> list:
    """``bpy.data.objects.values()``: one list (indexing the collection walks it, O(i) a
    call), made once within :func:`one_pass` and again after each update in it (see
    :func:`count`)."""
    if _memo is None:
        return bpy.data.objects.values()
    items = _memo.get("items")
    if items is None or len(items) != count():
        items = _memo["items"] = bpy.data.objects.values()
    return items


def evaluate(view_layer) -> None:
    """``view_layer.update()`` within a pass: every handler runs inside it (another
    add-on's may add or delete objects), so :func:`count` walks the list again after it."""
    view_layer.update()
    after_update()


def after_update() -> None:
    """Something ran that may have run handlers (an update, an operator): :func:`count`
    walks the list again at its next call, and a view layer's list is read again."""
    if _memo is not None:
        _memo.pop("n", None)
        _memo.pop("items", None)
        _memo.pop("layers", None)


def layer_objects(view_layer) -> tuple[np.ndarray, list]:
    """``(uids, items)`` of ``view_layer.objects``: their identities (:func:`uids`) and one
    list of them (indexing the collection walks it), read once within :func:`one_pass`
    (the candidates and the policy's bystanders both ask) and again after each update in
    it (handlers may add or remove objects: :func:`after_update`)."""
    if _memo is None:
        return uids(view_layer.objects), view_layer.objects.values()
    layers = _memo.setdefault("layers", {})
    key = view_layer.as_pointer()
    hit = layers.get(key)
    if hit is None:
        hit = layers[key] = (uids(view_layer.objects), view_layer.objects.values())
    return hit[0].copy(), hit[1]


def forget() -> None:
    """Undo, redo or a file load replaced Blender's data (or the add-on goes away): the
    records kept across passes are read again."""
    _kept.clear()


def _recall(prop):
    """The kept record ``prop``, if it was over the objects there are now (one bulk read
    of their identities, within a pass shared with every other use)."""
    kept = _kept.get(prop)
    if kept is None:
        return None
    ids = uids()
    return kept[1] if len(ids) == len(kept[0]) and np.array_equal(ids, kept[0]) else None


def _keep(prop, values) -> None:
    if HAS_SESSION_UID:
        _kept[prop] = (uids(), values.copy())


def flags(prop, collection=None):
    """``(n,) bool`` of a boolean property over ``collection`` (default ``bpy.data.objects``)."""
    objs = bpy.data.objects if collection is None else collection
    record = collection is None and prop in RECORDS
    n = count() if collection is None else len(objs)
    if record:
        hit = _memo.get(prop) if _memo is not None else None
        if hit is None or len(hit) != n:
            hit = _recall(prop)
            if hit is not None and _memo is not None:
                _memo[prop] = hit.copy()
        if hit is not None:
            return hit.copy()
    out = np.zeros(n, dtype=bool)
    objs.foreach_get(prop, out)
    if record:
        if _memo is not None:
            _memo[prop] = out.copy()
        _keep(prop, out)
    return out


def layer_flags(prop, layer_uids: np.ndarray, layer_objects):
    """``(k,) bool``: :func:`flags` of ``prop`` over a view layer's objects
    (``layer_objects``, their identities ``layer_uids``): within :func:`one_pass`, a record
    is taken from its one read over ``bpy.data.objects`` (every object of a view layer
    is one of them)."""
    if _memo is None or prop not in RECORDS:
        return flags(prop, layer_objects)
    data = flags(prop)
    ids = uids()
    order = _memo.get("order")
    if order is None or len(order) != len(ids):
        order = _memo["order"] = np.argsort(ids, kind="stable")
    return data[order[np.searchsorted(ids, layer_uids, sorter=order)]]


def store(prop, values, at=None):
    """Write record ``prop`` over ``bpy.data.objects``: all of ``values`` (``(n,) bool``)
    in bulk, or item by item at indices ``at`` (few changed)."""
    values = np.ascontiguousarray(values, dtype=bool)
    if at is None:
        bpy.data.objects.foreach_set(prop, values)
    else:
        items = objects()
        for i in at:
            setattr(items[i], prop, bool(values[i]))
    if _memo is not None:
        _memo[prop] = values.copy()
    _keep(prop, values)


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
    memo = _memo if collection is None else None
    n = count() if collection is None else len(objs)
    if memo is not None:                           # within one pass (see one_pass): read once
        hit = memo.get("uids")
        if hit is not None and len(hit) == n:
            return hit.copy()
        memo.pop("order", None)
    if not HAS_SESSION_UID:
        out = idents(objs)
    else:
        out = np.zeros(n, dtype=np.int64)
        objs.foreach_get("session_uid", out)
    if memo is not None:
        memo["uids"] = out.copy()
    return out


_SESSION_UID = attrgetter("session_uid")


def idents(items) -> np.ndarray:
    """``(n,) int64`` identities (:func:`ident`) of a sequence of datablocks (a list
    such as ``context.visible_objects``): one attribute read each, no call."""
    if HAS_SESSION_UID:
        return np.fromiter(map(_SESSION_UID, items), dtype=np.int64, count=len(items))
    return np.array([o.as_pointer() for o in items], dtype=np.int64)


def pick(items, index: list) -> list:
    """``[items[i] for i in index]`` (``index``: a list of ints) in one C call: a list of
    50,000 objects is taken in a fraction of the comprehension's time."""
    if len(index) > 1:
        return list(itemgetter(*index)(items))
    return [items[i] for i in index]
