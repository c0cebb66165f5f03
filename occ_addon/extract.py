"""From Blender to the engine's arrays: the engine's picture is what Blender would draw now.

One principle, applied at this boundary only: an object takes part in a pass
(a *candidate*: an occluder, and hidden where occluded) when Blender draws it
now as solid geometry from the evaluated depsgraph, or when the add-on itself
hid it and Blender would draw it now had the add-on not.  For the latter the
add-on must know its current evaluated state, which Blender does not compute
for hidden objects; it knows it only for *static* objects (nothing but an edit
can change them: no animation, drivers, constraints, physics, particles,
geometry nodes, instancing, modifiers that read other objects or time, and the
same for every parent), from the geometry read while it was shown and its
transform rebuilt from ``matrix_basis`` through the parent chain.  Everything
else is handled conservatively by construction:

- *dynamic* objects (above) are never hidden (:func:`.kinds.is_dynamic`); one the
  add-on had hidden is shown again before the pass (so it is evaluated now);
- an object the user hid in any way is no candidate (and one the add-on had
  hidden is given back to the user's hide);
- an object the pass's 3D view does not draw (local view, local collections,
  the view's object-type filters; :func:`.cameras.pass_view`) is no candidate (and
  one the add-on had hidden is given back): what the view does not draw occludes
  nothing in it;
- wire and bounds display, "in front" display, and every type that is not solid mesh-like geometry
  (point clouds, volumes, grease pencil, hair curves, empties, lights): never
  occluders and never hidden;
- children drawn only as vertex/face instances: not candidates (not drawn
  where they stand);
- an object whose matrix or vertices are NaN or infinite: not a candidate,
  named in a warning, never hidden;
- instances as Blender draws them (``depsgraph.object_instances``): a
  collection instance carries its instanced geometry and is hidden as a unit;
  a geometry-nodes, particle or vertex/face instancer carries its own mesh
  (where drawn) and its instances, as an occluder, and is never hidden (it is
  dynamic: hidden, it would not be evaluated).

Objects are identified by ``session_uid`` (unique for the Blender session,
kept by renames; see :func:`.identity.ident` for Blender 3.4); caches are
keyed by it and by the mesh datablock's id, and are dropped on undo, redo and
file load (:meth:`Session.reset`), where Blender may give an unchanged id back
with other contents.

Each pass asks two questions of different cost: which objects take part and
where they are (:meth:`Extractor.candidates`: what is drawn in one list, flags and
world matrices in one ``foreach_get`` each, kinds looked up in bulk and classified
one by one only where unknown), and what they look like
(:meth:`Extractor.scene_steps`, ``to_mesh`` per changed object, only when the set of
objects or some geometry changed; the depsgraph and frame-change handlers mark
what changed).

This module holds both questions (:class:`Candidates`, :class:`Extractor`); what they
ask of Blender lives beside it: what an object is (:mod:`.kinds`), what a view draws
(:mod:`.drawn`), meshes and instances read in bulk (:mod:`.meshes`, :mod:`.instances`),
and what a hidden object's geometry was read from (:mod:`.fingerprints`).
"""

import time
from collections.abc import Generator, Iterable
from dataclasses import dataclass

import bpy
import numpy as np

from ..core import OccError, Scene
from . import identity, materials
from .cameras import pass_view
from .drawn import NoView, drawn, filters_geometry, shown_by_collections, user_shown, view_shows
from .fingerprints import fingerprint
from .identity import ident
from .instances import UNREAD, instanced_geometry
from .kinds import CODES, KINDS, UNKNOWN, BulkMap, Kind, ObjectInfo, instanced_sources, is_dynamic, kind
from .meshes import COPY_VERTICES, SHARED_ARRAYS, mesh_arrays
from .worker import Progress

STEP_S = 0.1                                     # geometry reading yields about this often (modal steps)


@dataclass(frozen=True, slots=True, eq=False)
class Geometry:
    """An object's cached geometry: ``key`` names the mesh it was read from (shared
    meshes share one: ``("mesh", mesh id)``; ``("object", uid)``; a collection
    instance ``("instance", uid, its members' sorted ids)``), ``vertices`` ``(v, 3)``
    local positions (None: not all finite), ``faces`` ``(f, 3)`` triangles."""

    key: tuple
    vertices: np.ndarray | None
    faces: np.ndarray


def bulk_matrices(collection, prop: str, index=None) -> np.ndarray:
    """``(n, 4, 4) float64`` of a matrix property over a whole collection, one ``foreach_get``
    (``index``: only those items' rows, taken before the conversion).

    Blender stores matrices column-major and in float32, so the float32 read is exact.
    """
    flat = np.empty(len(collection) * 16, dtype=np.float32)
    collection.foreach_get(prop, flat)
    m = flat.reshape(-1, 4, 4)
    if index is not None:
        m = m[index]
    return m.transpose(0, 2, 1).astype(np.float64)


def world_matrix(obj) -> np.ndarray:
    """World matrix ``(4, 4)``.  An object the add-on hid is not evaluated by the
    depsgraph (its ``matrix_world`` goes stale), so its matrix is rebuilt from
    the parent chain and ``matrix_basis`` (exact for static objects: no
    constraints, drivers or bone parents, see :func:`is_dynamic`)."""
    if not obj.occ_culled:
        return np.array(obj.matrix_world, dtype=np.float64)
    m = np.array(obj.matrix_basis, dtype=np.float64)
    if obj.parent is not None:
        m = world_matrix(obj.parent) @ np.array(obj.matrix_parent_inverse, dtype=np.float64) @ m
    return m


class Candidates:
    """The objects that take part in a pass, in view-layer order.

    objects: bpy objects; uids: ``(n,) int64`` session ids; kinds: see :func:`kind`
    (codes: ``(n,) int8``, the same as indices into :data:`KINDS`); layer_index:
    ``(n,) int64`` position in ``view_layer.objects``;
    culled: ``(n,) bool`` hidden by the add-on now; stale: of them, those hidden
    everywhere (not evaluated: their geometry is the cached one); matrices: ``(n, 4, 4)``
    world matrices.  give_back: ``(m,) int64`` session ids of objects the add-on
    hid and must show again (the user hid them too, or their state is unknown);
    bad: names of objects left out for NaN or infinite values.
    """

    def __init__(self, view_layer, extractor: "Extractor", verify: bool = False, space=None,
                 depsgraph=None, every: bool = False):
        """space: the pass's 3D view (``SpaceView3D``, see :func:`.cameras.pass_view`):
        what it does not draw takes no part; None: Blender's default view (the
        context's 3D view, if any).  depsgraph: the view layer's, evaluated: the world
        matrices of the objects whose originals may be stale (see
        :meth:`Extractor.fresh_matrices`; ``every``: of every evaluated candidate)."""
        self.view_layer = view_layer
        layer = view_layer.objects
        uids_all, items = identity.layer_objects(view_layer)
        stale_all = identity.layer_flags("occ_culled", uids_all, layer)     # hidden everywhere: not evaluated
        culled_all = stale_all | identity.layer_flags(identity.VIEW_RECORD, uids_all, layer)
        info = extractor.info
        no_instances = filters_geometry(space)
        # drawn now, or hidden by the add-on: only those can take part (what else the user
        # or the view hides is not looked at one by one)
        shown = drawn(view_layer, uids_all, space)
        # hidden in one view only, what the user shows is what the view layer shows
        base = drawn(view_layer, uids_all, NoView.BASE) if (culled_all & ~stale_all).any() else None
        sel = np.flatnonzero(shown | culled_all)
        codes = info.codes_of(uids_all[sel])
        culled_sel, stale_sel = culled_all[sel], stale_all[sel]
        keep = codes > CODES[None]
        if no_instances:
            keep &= codes != CODES[Kind.COLLECTION]
        # in bulk, pass after pass: what is known and shown, and what the add-on hides in one
        # view only (evaluated: its edits are reported) where the view draws every geometry
        # type, the view layer shows it and its geometry is cached and unchanged
        bulk = (codes != UNKNOWN) & ~culled_sel
        give_back, memo = [], {}
        if base is not None and (space is None or not (space.use_local_collections or no_instances)):
            viewed = culled_sel & ~stale_sel & ((codes == CODES[Kind.MESH]) | (codes == CODES[Kind.INSTANCER]))
            if viewed.any():
                at = np.flatnonzero(viewed)
                fine = base[sel[at]] & extractor.geometry_known(uids_all[sel[at]])
                bulk[at] = True
                keep[at] = fine
                give_back = uids_all[sel[at[~fine]]].tolist()
        rest = np.flatnonzero(~bulk)
        new = rest[~culled_sel[rest]]
        if len(new):                                  # not known yet (a first pass): what each is, in one sweep
            found = [items[i] for i in sel[new].tolist()]
            entries = [ObjectInfo(kind(o), o.parent is not None) for o in found]
            info.update(uids_all[sel[new]].tolist(), entries)
            c = np.array([CODES[e.kind] for e in entries], dtype=codes.dtype)
            codes[new] = c
            keep[new] = (c > CODES[None]) & ~(no_instances & (c == CODES[Kind.COLLECTION]))
        for j in rest[culled_sel[rest]].tolist():     # the rest one by one: hidden by the add-on
            i = int(sel[j])
            o, uid, stale = items[i], int(uids_all[i]), bool(stale_all[i])
            keep[j] = False
            if stale and verify:                      # edits to hidden objects are not reported
                extractor.forget(uid)
            entry = info.get(uid)
            if entry is None:
                entry = info[uid] = ObjectInfo(kind(o), o.parent is not None)
            k = entry.kind
            # it takes no part, the user hid it too, or it may have changed unseen: give it
            # back (hidden in one view only, it is evaluated and its edits are reported)
            if k is None or (no_instances and k is Kind.COLLECTION) \
                    or not (base[i] if not stale else extractor.user_shown(o, uid, view_layer)) \
                    or not extractor.knows(o, k) \
                    or (stale and (extractor.is_dynamic(o, uid)
                                   or (verify and not extractor.unchanged(o, uid, k, memo)))) \
                    or (space is not None and not view_shows(o, space, stale)):
                give_back.append(uid)
                continue
            keep[j], codes[j] = True, CODES[k]
        index, codes = sel[keep].tolist(), codes[keep]
        kinds = identity.pick(KINDS, codes.tolist())
        objects = identity.pick(items, index)
        index = np.array(index, dtype=np.int64)
        self.culled = culled_all[index]
        self.stale = stale_all[index]
        m = bulk_matrices(layer, "matrix_world", index) if len(index) else np.zeros((0, 4, 4))
        hidden = np.flatnonzero(stale_all[index])
        if len(hidden):                               # stale matrix_world: rebuilt from matrix_basis
            m[hidden] = bulk_matrices(layer, "matrix_basis", index[hidden])
            for k in hidden:
                if info[int(uids_all[index[k]])].parented:   # through the parent chain
                    m[k] = world_matrix(objects[k])
        if depsgraph is not None:
            extractor.fresh_matrices(objects, uids_all[index], ~stale_all[index], m, depsgraph, every)
        finite = np.all(np.isfinite(m), axis=(1, 2))
        self.bad = [objects[k].name for k in np.flatnonzero(~finite)]
        keep = np.flatnonzero(finite)
        if len(keep) < len(objects):                  # else every one (the usual case)
            objects, kinds = identity.pick(objects, keep.tolist()), identity.pick(kinds, keep.tolist())
        self.objects, self.kinds = objects, kinds
        self.codes = codes[keep]                      # the kinds as BulkMap codes (KINDS)
        self.layer_index, self.culled, self.matrices = index[keep], self.culled[keep], m[keep]
        self.stale = self.stale[keep]
        self.uids = uids_all[self.layer_index]
        self.give_back = np.array(give_back, dtype=np.int64)

    def __len__(self):
        return len(self.objects)


class Extractor:
    """Keeps the last extraction and refreshes only what changed (keys: session ids)."""

    def __init__(self):
        self.cache: dict[int, Geometry] = {}   # object uid -> its geometry as last read
        # uid -> the mark's number: a read consumes only marks made before it began
        self.dirty = {}          # object uids whose geometry changed
        self.touched = {}        # object uids whose geometry or transform changed (instanced collections)
        self.marks = 0
        # What an object is, from its settings (edits report it: :meth:`saw` forgets it):
        self.info = BulkMap(lambda entry: CODES[entry.kind])
        self.dynamic = BulkMap(int)   # uid -> is_dynamic
        self.shown = {}          # uid -> user_shown (hidden by the add-on); any visibility change clears it
        self.shown_ids = None    # sorted uids of the objects in shown collections (see shown_by_collections)
        self.fps = {}            # uid -> fingerprint of the data its cached geometry was read from (seal)
        self.sources = {}        # instancer uid -> its instanced_sources when its instances were read
        self.beyond: set[int] = set()   # instancers whose instances, as read, draw beyond their geometry
        self.stale_originals = set()  # uids whose original matrix_world lags their evaluated one
        materials.forget()

    def forget(self, uid: int) -> None:
        """Forget what object ``uid`` is (it will be classified again)."""
        self.info.pop(uid, None)
        self.dynamic.pop(uid, None)

    def seal(self, objects: list, uids: np.ndarray) -> None:
        """Before ``objects`` (session ids ``uids``) are hidden everywhere (from then on
        not evaluated, their edits not reported): fingerprint the data their cached
        geometry was read from (:meth:`unchanged` compares against it), where not done
        since that read.  Until then the object was shown, so every edit of it was
        reported: one with a change marked since its read gets no fingerprint, and is
        given back by the next check (conservative)."""
        memo = {}
        for obj, uid in zip(objects, uids.tolist(), strict=True):
            if uid in self.fps or uid in self.dirty or uid not in self.cache:
                continue
            entry = self.info.get(uid)
            if entry is not None and entry.kind is not None:
                self.fps[uid] = fingerprint(obj, entry.kind, memo)

    def unchanged(self, obj, uid: int, k: Kind, memo: dict) -> bool:
        """Whether the data of ``obj`` (hidden by the add-on, so not evaluated, and its
        edits not reported) is what its cached geometry was read from."""
        fp = self.fps.get(uid)
        return fp is not None and fp == fingerprint(obj, k, memo)

    def saw(self, update) -> None:
        """A depsgraph update (not our own): forget what it may have changed.  An
        object's edits report it (while it is shown); eye, collection and view-layer
        changes report the scene or a collection."""
        idb = update.id
        if isinstance(idb, bpy.types.Object):
            uid = ident(idb.original)
            self.info.pop(uid, None)
            self.shown.pop(uid, None)
            if self.dynamic and self.dynamic.pop(uid, None) is not True and is_dynamic(idb.original):
                self.dynamic.clear()                  # its children may have become dynamic with it
        else:
            if type(idb).__name__ in materials.UPDATES:   # what an object is may change with its materials
                materials.forget()
                self.info.clear()
                for uid in self.sources:              # instances are read without the see-through ones
                    self.cache.pop(uid, None)
            self.visibility_changed()

    def visibility_changed(self) -> None:
        """Eye, collection or view-layer visibility may have changed."""
        self.shown.clear()
        self.shown_ids = None

    def user_shown(self, obj, uid: int, view_layer) -> bool:
        hit = self.shown.get(uid)
        if hit is None:
            if self.shown_ids is None:
                self.shown_ids = shown_by_collections(view_layer)
            hit = self.shown[uid] = bool(user_shown(obj, view_layer, self.shown_ids))
        return hit

    def is_dynamic(self, obj, uid: int, memo: dict | None = None) -> bool:
        hit = self.dynamic.get(uid)
        if hit is None:
            hit = self.dynamic[uid] = is_dynamic(obj, memo)
        return hit

    def dynamic_of(self, objects: list, uids: np.ndarray, at: np.ndarray) -> np.ndarray:
        """``(len(at),) bool``: :meth:`is_dynamic` of ``objects[at]`` (session ids
        ``uids[at]``), looked up in bulk, asked one by one where not known."""
        out = self.dynamic.codes_of(uids[at]).astype(np.int64)
        memo = {}                                     # object data -> animated, once a call
        for j in np.flatnonzero(out == UNKNOWN).tolist():
            k = int(at[j])
            out[j] = self.is_dynamic(objects[k], int(uids[k]), memo)
        return out.astype(bool)

    def mark(self, geometry: Iterable[int] = (), transform: Iterable[int] = ()) -> None:
        """Record depsgraph updates: uids whose geometry changed, and uids that moved
        or changed otherwise (what instances them may be stale)."""
        self.marks += 1
        self.dirty.update(dict.fromkeys(geometry, self.marks))
        self.touched.update(dict.fromkeys(geometry, self.marks))
        self.touched.update(dict.fromkeys(transform, self.marks))

    def candidates(self, context, verify: bool = False, every: bool = False) -> "Candidates":
        """The pass's candidates; ``verify``: check every object the add-on hides
        against the data its geometry was read from (see :func:`fingerprint`);
        ``every``: compare every evaluated candidate's original world matrix with its
        evaluated one (:meth:`fresh_matrices`), not only those found stale before."""
        depsgraph = context.evaluated_depsgraph_get() if every or self.stale_originals else None
        return Candidates(context.view_layer, self, verify, pass_view(context), depsgraph, every)

    def fresh_matrices(self, objects: list, uids: np.ndarray, evaluated: np.ndarray, m: np.ndarray,
                       depsgraph, every: bool) -> None:
        """Where an original ``matrix_world`` lags the evaluated one, take the evaluated.

        Blender writes evaluated transforms back to the originals only from the active
        depsgraph: an object moved (through a parent, a constraint, a driver) while
        another view layer's depsgraph was the one evaluated, or evaluated while not
        active (background scripts), keeps a stale original until something tags it.
        The candidates read originals in bulk; after a view-layer switch (and on a Cull
        click, in files with several view layers or scenes) every evaluated candidate is
        compared (``every``: 0.19 s at 50,000 objects on bpy 5.0.1, one ``evaluated_get``
        each), and the ones found stale are read from their evaluated copies on every
        pass until their originals agree.  Nothing is tagged or evaluated for this:
        tagging a transform the user never changed is what let the add-on trigger
        Blender's crash after an emitter's delete and undo (issue 30; the rule in
        :mod:`.session`).  ``objects``, ``uids``, ``evaluated`` (``(n,) bool``: in the
        depsgraph, not hidden everywhere) and ``m`` (``(n, 4, 4)``, updated in place)
        are the candidates'."""
        at = np.flatnonzero(evaluated)
        if not every:
            at = at[np.isin(uids[at], np.fromiter(self.stale_originals, dtype=np.int64,
                                                  count=len(self.stale_originals)))]
            self.stale_originals.difference_update(uids[at].tolist())
        elif not self.stale_originals.isdisjoint(uids.tolist()):
            self.stale_originals.difference_update(uids.tolist())
        for k in at.tolist():
            o = objects[k]
            e = o.evaluated_get(depsgraph).matrix_world
            if e != o.matrix_world:
                m[k] = np.array(e, dtype=np.float64)
                self.stale_originals.add(int(uids[k]))

    def matrices(self, cand: "Candidates", kept: np.ndarray) -> np.ndarray:
        """World matrices ``(k, 4, 4)`` of candidates ``kept`` (read in bulk with the candidates)."""
        return cand.matrices[kept]

    def knows(self, obj, k: Kind) -> bool:
        """Whether the geometry of ``obj`` (hidden by the add-on) is cached and current."""
        hit = self.cache.get(ident(obj))
        if hit is None:
            return False
        if k is Kind.COLLECTION:
            return not self._instance_stale(obj)
        return ident(obj) not in self.dirty

    def geometry_known(self, uids: np.ndarray) -> np.ndarray:
        """``(n,) bool``: :meth:`knows` in bulk for objects that instance no collection:
        their geometry is cached and no change was marked since."""
        out = np.isin(uids, np.fromiter(self.cache.keys(), dtype=np.int64, count=len(self.cache)))
        if self.dirty:
            out &= ~np.isin(uids, np.fromiter(self.dirty.keys(), dtype=np.int64, count=len(self.dirty)))
        return out

    def check_shown(self, cand: "Candidates") -> None:
        """Objects the add-on hid everywhere and has shown again since (their fingerprint
        from :meth:`seal` still stands: no read since): an edit made while one was hidden
        was reported by no evaluation, and the add-on's own show is no edit (its report is
        ignored), so each is compared once with the data its cached geometry was read
        from, and read again where that changed (workflow seed 7207: a linked duplicate's
        shared mesh edited while the add-on hid it, shown again when the view left the
        hidden set's envelope, then hidden by the next pass behind its old, smaller shape)."""
        if not self.fps:
            return
        shown = np.flatnonzero(np.isin(cand.uids, np.fromiter(self.fps, dtype=np.int64, count=len(self.fps)))
                               & ~cand.stale)
        memo: dict = {}
        changed = []
        for i in shown.tolist():
            uid = int(cand.uids[i])
            if self.fps.pop(uid) != fingerprint(cand.objects[i], cand.kinds[i], memo):
                changed.append(uid)
        if changed:
            self.mark(geometry=changed)

    def needs_geometry(self, cand: "Candidates") -> bool:
        """Whether :meth:`scene_steps` must read geometry again for these candidates.
        Instancers are asked whatever was reported: what they instance may change
        unreported (a deleted particle object or collection member)."""
        if not self.dirty.keys().isdisjoint(cand.uids.tolist()):
            return True
        memo = {}                                     # collection -> its members, once a pass
        for i in np.flatnonzero((cand.codes != CODES[Kind.MESH]) & ~cand.stale).tolist():
            o, k = cand.objects[i], cand.kinds[i]
            if (k is Kind.COLLECTION and self._instance_stale(o, memo)) \
                    or (k is Kind.INSTANCER and self._instancer_stale(o)):
                return True
        return False

    def forget_changes(self, seen: int) -> None:
        """Changes marked up to mark number ``seen`` (taken before a read began) are
        consumed; any reported during the read (between steps) stay for the next one."""
        self.dirty = {u: m for u, m in self.dirty.items() if m > seen}
        self.touched = {u: m for u, m in self.touched.items() if m > seen}

    def scene_steps(self, context, cand: "Candidates") -> Generator[tuple, None, tuple[Scene, np.ndarray, list]]:
        """A generator (see :func:`.worker.drive`) that returns ``(core.Scene, kept,
        bad)``: the engine's scene of the candidates with finite triangles, ``kept``
        their indices into ``cand``, ``bad`` the names left out for NaN or infinite
        vertices.  It yields :class:`.worker.Progress` about every :data:`STEP_S` seconds
        while it reads geometry (a modal operator redraws and looks for Esc in
        between).  Stopped early, what it read stays cached and nothing else changes."""
        seen = self.marks
        depsgraph = context.evaluated_depsgraph_get()
        fresh = {ident(o): o for o, k, c in zip(cand.objects, cand.kinds, cand.stale, strict=True)
                 if not c and ((k is Kind.COLLECTION and self._instance_stale(o))
                               or (k is Kind.INSTANCER and self._instancer_stale(o)))}
        beyond: set[int] = set()
        read_instances = instanced_geometry(depsgraph, fresh, beyond)
        self.beyond = (self.beyond - fresh.keys()) | beyond
        for uid, (v, f) in read_instances.items():
            o = fresh[uid]
            if v is UNREAD[0]:                    # kept visible, never an occluder (core.Scene.invalid)
                self.cache[uid] = Geometry(("unknown", uid), v, f)
                self.fps[uid] = fingerprint(o, Kind.INSTANCER, {})
                self.sources[uid] = instanced_sources(o)
                continue
            # instancer-local (a move is then a matrix), by the same evaluation as the instances
            inv = _inverse(np.array(o.evaluated_get(depsgraph).matrix_world, dtype=np.float64))
            v = v @ inv[:3, :3].T + inv[:3, 3]
            if o.type == "EMPTY":
                key = ("instance", uid, _members(o.instance_collection))
            else:                                  # its own mesh, where drawn, and its instances
                key = ("object", uid)
                if o.show_instancer_for_viewport:
                    ov, of = mesh_arrays(o.evaluated_get(depsgraph))
                    v, f = np.concatenate([ov, v]), np.concatenate([of, f.astype(np.int64) + len(ov)])
            self.cache[uid] = Geometry(key, _finite_or_none(v), f)
            self.fps[uid] = fingerprint(o, Kind.COLLECTION if o.type == "EMPTY" else Kind.INSTANCER, {})
            if o.type != "EMPTY":
                self.sources[uid] = instanced_sources(o)
        uids, meshes, mesh_of, kept, bad = [], [], [], [], []
        mesh_index, read = {}, {}
        n = len(cand.objects)
        due = time.perf_counter() + STEP_S
        stale, cand_uids = cand.stale.tolist(), cand.uids.tolist()
        for i, obj in enumerate(cand.objects):         # once per object, bulk inside
            if time.perf_counter() >= due:
                yield Progress("reading geometry", i / n)
                due = time.perf_counter() + STEP_S
            uid = cand_uids[i]
            entry = self._geometry(obj, uid, cand.kinds[i], stale[i], depsgraph, read)
            if entry is None:
                continue
            key, v, f = entry.key, entry.vertices, entry.faces
            if v is None:
                bad.append(obj.name)
                continue
            if len(f) == 0:
                continue
            if key not in mesh_index:
                mesh_index[key] = len(meshes)
                meshes.append((v, f))
            uids.append(uid)
            mesh_of.append(mesh_index[key])
            kept.append(i)
        self.forget_changes(seen)
        if not uids:
            raise OccError("nothing to cull: the view layer has no visible mesh objects"
                           + (f" (left out for NaN or infinite values: {', '.join(bad)})" if bad else ""))
        kept = np.array(kept, dtype=np.int64)
        objects = [cand.objects[i] for i in kept]
        tree_parent, tree_object = _tree(context.scene, objects, uids)
        scene = Scene.from_arrays([o.name for o in objects], meshes, np.array(mesh_of),
                                  cand.matrices[kept], tree_parent, tree_object)
        return scene, kept, bad

    def _instance_stale(self, obj, memo=None):
        hit = self.cache.get(ident(obj))
        if hit is None:
            return True
        c = obj.instance_collection
        members = memo.get(ident(c)) if memo is not None else None
        if members is None:
            members = _members(c)
            if memo is not None:
                memo[ident(c)] = members
        return hit.key[2] != members or not self.touched.keys().isdisjoint(members)

    def _instancer_stale(self, obj):
        """Whether the cached instances of an instancer may differ from what Blender
        draws: never read, its own data changed, or an object it may instance changed
        (its geometry or transform: a vertex-instanced child, a particle system's
        object or collection; for geometry nodes, which can instance anything, any
        object), or it may instance other objects than when it was read (a deleted
        particle object or collection member is never reported itself, and the
        instancer is reported with neither flag).  Its instances occlude: stale ones
        could hide what is visible."""
        uid = ident(obj)
        if uid in self.dirty or uid not in self.cache:
            return True
        sources = instanced_sources(obj)
        # conservative by construction: other sources than those read, whatever was
        # reported (a deletion need not report anything that touches this instancer)
        if sources is not None and sources != self.sources.get(uid):
            return True
        if not self.touched:
            return False
        # sources unknown (geometry nodes: anything touched may be one) or one of them touched
        return sources is None or not self.touched.keys().isdisjoint(sources)

    def _geometry(self, obj, uid, k, culled, depsgraph, read):
        """The object's (session id ``uid``) :class:`Geometry` from the cache when still
        valid, else from the depsgraph (a shared mesh once per pass: ``read``); None when
        unknown.  Its vertices are None for geometry with NaN or infinite vertices."""
        hit = self.cache.get(uid)
        if k is not Kind.MESH or culled:                     # instancers: read above; hidden: not evaluated
            return hit
        shared = obj.type == "MESH" and not obj.modifiers and obj.data.users > 1
        key = ("mesh", ident(obj.data)) if shared else ("object", uid)
        if hit is not None and hit.key == key and uid not in self.dirty:
            return hit
        if key not in read:
            ev = obj.evaluated_get(depsgraph)
            direct = obj.type == "MESH" and not obj.modifiers and obj.mode != "EDIT" \
                and (not SHARED_ARRAYS or len(ev.data.vertices) < COPY_VERTICES)
            v, f = mesh_arrays(ev, direct)
            read[key] = (_finite_or_none(v), f)
        v, f = read[key]
        hit = self.cache[uid] = Geometry(key, v, f)
        self.fps.pop(uid, None)                    # fingerprinted when hidden everywhere (seal)
        return hit


def _finite_or_none(v):
    return v if np.all(np.isfinite(v)) else None


def _inverse(m):
    """Inverse of a world matrix; for a singular one (a scale of 0) the pseudo-inverse,
    which still maps the instance's (flat) world geometry back exactly."""
    try:
        return np.linalg.inv(m)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(m)


def _members(collection):
    """Session ids of the objects an instanced collection brings, as a sorted tuple."""
    return tuple(sorted(ident(o) for o in collection.all_objects))


def _tree(scene, objects, uids):
    """Scene tree over collections (groups) and objects (session ids ``uids``; parents kept)."""
    index = dict(zip(uids, range(len(uids)), strict=True))
    parent, carried, node_of = [], [], {}

    def walk(coll, parent_node):                      # collections: a handful, recursion ok
        node = len(parent)
        parent.append(parent_node)
        carried.append(-1)
        for uid in identity.uids(coll.objects).tolist():
            if uid in index and uid not in node_of:
                node_of[uid] = len(parent)
                parent.append(node)
                carried.append(index[uid])
        for child in coll.children:
            walk(child, node)

    walk(scene.collection, -1)
    parent = np.array(parent, dtype=np.int64)
    carried = np.array(carried, dtype=np.int64)
    for obj, uid in zip(objects, uids, strict=True):  # object parenting refines the tree
        p = obj.parent
        if p is not None and uid in node_of and ident(p) in node_of:
            parent[node_of[uid]] = node_of[ident(p)]
    return parent, carried
