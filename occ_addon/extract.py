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

- *dynamic* objects (above) are never hidden (:func:`is_dynamic`); one the
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
"""

import ctypes
import time
import zlib
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass
from enum import Enum

import bpy
import numpy as np

from ..core import OccError, Scene
from . import identity
from .cameras import pass_view
from .identity import ident
from .worker import Progress

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
SOLID_DISPLAY = {"SOLID", "TEXTURED"}            # wire and bounds display never occlude
STEP_S = 0.1                                     # geometry reading yields about this often (modal steps)
_EMPTY = (np.zeros((0, 3), dtype=np.float32), np.zeros((0, 3), dtype=np.int32))


class Kind(Enum):
    """How an object can take part, by its settings alone."""

    MESH = "mesh"
    INSTANCER = "instancer"      # mesh-like, brings instances: its own geometry (where drawn) and theirs
    COLLECTION = "collection"    # an empty that instances a collection


@dataclass(frozen=True, slots=True)
class ObjectInfo:
    """What an object is, from its settings (edits report it: :meth:`Extractor.saw`
    forgets it): its :func:`kind` and whether it has a parent."""

    kind: Kind | None
    parented: bool


# Kind as a small integer, for lookups in bulk (BulkMap codes): UNKNOWN -1, 0 none
KINDS = (None, Kind.MESH, Kind.INSTANCER, Kind.COLLECTION)
CODES = {k: i for i, k in enumerate(KINDS)}
UNKNOWN = -1


class BulkMap:
    """``uid -> value`` (a dict's ``get``, ``[]``, ``pop``, ``clear``) with each value's
    small-integer code (``code(value)``) mirrored in sorted arrays, so that a pass looks
    up every object in one ``searchsorted`` and asks one by one only what it has not
    seen (or what an edit made it forget): what an object is (:class:`ObjectInfo`) and
    whether it is dynamic (:func:`is_dynamic`)."""

    def __init__(self, code: Callable[[object], int]):
        self.code = code
        self.entries: dict[int, object] = {}
        self.uids = np.zeros(0, dtype=np.int64)        # sorted
        self.codes = np.zeros(0, dtype=np.int8)        # code(value), UNKNOWN where forgotten
        self.pending: dict[int, int] = {}              # set since the arrays were merged

    def __len__(self):
        return len(self.entries)

    def clear(self) -> None:
        self.__init__(self.code)

    def get(self, uid: int):
        return self.entries.get(uid)

    def __getitem__(self, uid: int):
        return self.entries[uid]

    def __setitem__(self, uid: int, value) -> None:
        self.entries[uid] = value
        self.pending[uid] = self.code(value)

    def update(self, uids: list, values: list) -> None:
        """``self[u] = v`` for each pair, at once."""
        self.entries.update(zip(uids, values, strict=True))
        self.pending.update(zip(uids, map(self.code, values), strict=True))

    def pop(self, uid: int, default=None):
        entry = self.entries.pop(uid, default)
        self.pending.pop(uid, None)
        k = int(np.searchsorted(self.uids, uid))
        if k < len(self.uids) and self.uids[k] == uid:
            self.codes[k] = UNKNOWN
        return entry

    def codes_of(self, uids: np.ndarray) -> np.ndarray:
        """``(n,) int8`` the codes of ``uids``' values (UNKNOWN: none)."""
        if self.pending:
            pu = np.fromiter(self.pending.keys(), dtype=np.int64, count=len(self.pending))
            pc = np.fromiter(self.pending.values(), dtype=np.int8, count=len(self.pending))
            self.pending = {}
            at = np.searchsorted(self.uids, pu)
            hit = at < len(self.uids)
            hit[hit] = self.uids[at[hit]] == pu[hit]
            self.codes[at[hit]] = pc[hit]
            if not hit.all():
                u, c = np.concatenate([self.uids, pu[~hit]]), np.concatenate([self.codes, pc[~hit]])
                order = np.argsort(u, kind="stable")
                self.uids, self.codes = u[order], c[order]
        out = np.full(len(uids), UNKNOWN, dtype=np.int8)
        if len(self.uids):
            at = np.minimum(np.searchsorted(self.uids, uids), len(self.uids) - 1)
            found = self.uids[at] == uids
            out[found] = self.codes[at[found]]
        return out


@dataclass(frozen=True, slots=True, eq=False)
class Geometry:
    """An object's cached geometry: ``key`` names the mesh it was read from (shared
    meshes share one: ``("mesh", mesh id)``; ``("object", uid)``; a collection
    instance ``("instance", uid, its members' sorted ids)``), ``vertices`` ``(v, 3)``
    local positions (None: not all finite), ``faces`` ``(f, 3)`` triangles."""

    key: tuple
    vertices: np.ndarray | None
    faces: np.ndarray

# Modifiers whose result depends only on the object's own data and settings
# (their animation, if any, is the object's animation_data); anything else
# (armature, hooks, booleans, geometry nodes, physics, ...) makes an object dynamic.
STATIC_MODIFIERS = {"SUBSURF", "MULTIRES", "MIRROR", "BEVEL", "SOLIDIFY", "TRIANGULATE", "WELD",
                    "DECIMATE", "EDGE_SPLIT", "WEIGHTED_NORMAL", "REMESH", "WIREFRAME", "SKIN",
                    "SMOOTH", "LAPLACIANSMOOTH", "CORRECTIVE_SMOOTH", "ARRAY", "SCREW"}


def positions(mesh) -> np.ndarray:
    """``(v, 3) float32`` vertex positions of a mesh, one bulk read: the ``position``
    attribute (Blender 3.5+, a plain array copy) or, where there is none (3.4),
    ``vertices.co``."""
    v = np.empty((len(mesh.vertices), 3), dtype=np.float32)
    attr = mesh.attributes.get("position")
    if attr is not None and attr.data_type == "FLOAT_VECTOR" and attr.domain == "POINT":
        attr.data.foreach_get("vector", v.reshape(-1))
    else:
        mesh.vertices.foreach_get("co", v.reshape(-1))
    return v


# Blender 4.0+ shares a mesh's arrays between copies until one is written: a ``to_mesh``
# copy costs next to nothing but its making (about 20 us), and the arrays a read un-shares
# (positions, the corners' vertices: the Python API reads them as if to write them) go with
# ``to_mesh_clear`` instead of staying beside the evaluated mesh (10 M-vertex grid,
# ``tools/blender_scale.py --only grid --steps``: first cull's peak 1,405 MB above the
# scene read from a copy, 1,672 MB read in place).  So a plain mesh of fewer than
# ``COPY_VERTICES`` vertices is read in place (a 50,000-object scene would pay a second for
# the copies), a larger one from a copy.  Before 4.0 a copy copies every vertex, edge and
# corner (~600 MB at 10 M vertices): a plain mesh is read in place.
SHARED_ARRAYS = bpy.app.version >= (4, 0, 0)
COPY_VERTICES = 4096


def mesh_arrays(obj_eval, direct: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Local vertices ``(v, 3) float32`` and triangles ``(f, 3) int32`` of an evaluated
    object, as Blender holds them (no wider copy: the engine takes both dtypes).

    direct: read the evaluated mesh itself rather than a ``to_mesh`` copy of it; only
    for a mesh object without modifiers outside edit mode, whose evaluated data is
    a plain mesh (edit mode and GPU subdivision give wrappers that only
    ``to_mesh`` turns into what Blender draws), and only where the copy would copy
    (see :data:`SHARED_ARRAYS`)."""
    if direct:
        return _read_mesh(obj_eval.data)
    mesh = obj_eval.to_mesh()
    if mesh is None:                     # e.g. an empty text object
        obj_eval.to_mesh_clear()
        return _EMPTY
    try:
        return _read_mesh(mesh)
    finally:
        obj_eval.to_mesh_clear()


def _read_mesh(mesh):
    mesh.calc_loop_triangles()
    v = positions(mesh)
    n = len(mesh.loop_triangles)
    f = _triangles_in_place(mesh, n) if n >= RAW_TRIANGLES else None
    if f is None:
        f = np.empty((n, 3), dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", f.reshape(-1))
    return v, f


# Above this many triangles a mesh's triangles are read from Blender's own array
RAW_TRIANGLES = 1 << 17
SAMPLES = 64         # triangles checked against the Python API's own answer


def _corner_vertices(mesh) -> np.ndarray:
    """``(c,) int32`` the vertex of every face corner, one bulk read."""
    out = np.empty(len(mesh.loops), dtype=np.int32)
    attr = mesh.attributes.get(".corner_vert")
    if attr is not None and attr.data_type == "INT" and attr.domain == "CORNER":
        attr.data.foreach_get("value", out)
    else:
        mesh.loops.foreach_get("vertex_index", out)
    return out


def _triangles_in_place(mesh, n: int) -> np.ndarray | None:
    """``(n, 3) int32`` triangles of a large mesh, or None: use ``foreach_get``.

    ``loop_triangles.foreach_get("vertices")`` computes each item on its own (6.2 s for
    20 M triangles here).  The triangles' corners lie in one array of Blender's (``int3``
    items in 4.1+, 16-byte ``MLoopTri`` before), so they are viewed where they lie, with
    the stride the items' addresses show, and mapped to vertices through the corners'
    vertex array (one bulk read): the whole mesh read takes 1.2 s instead of 6.6 s
    (``tools/blender_scale.py --only grid --steps``).  Trusted only where the items are evenly spaced
    and a spread of samples (first, last, seeded) reads the Python API's own ``loops``
    and ``vertices``; anything else: None."""
    tris = mesh.loop_triangles
    base = tris[0].as_pointer()
    stride = tris[1].as_pointer() - base
    if stride not in (12, 16) or tris[n - 1].as_pointer() - base != stride * (n - 1):
        return None
    raw = (ctypes.c_char * (stride * (n - 1) + 12)).from_address(base)
    corners = np.lib.stride_tricks.as_strided(np.frombuffer(raw, dtype=np.int32), shape=(n, 3),
                                              strides=(stride, 4), writeable=False)
    picks = np.unique(np.r_[0, n - 1, np.random.default_rng(n).integers(0, n, SAMPLES)]).tolist()
    if any(tuple(tris[i].loops) != tuple(corners[i].tolist()) for i in picks):
        return None
    to_vertex = _corner_vertices(mesh)
    if int(corners.min()) < 0 or int(corners.max()) >= len(to_vertex):
        return None
    f = np.empty((n, 3), dtype=np.int32)
    for a in range(0, n, 1 << 20):                    # in blocks: no index array of the whole
        np.take(to_vertex, corners[a:a + (1 << 20)], out=f[a:a + (1 << 20)])
    del to_vertex
    if any(tuple(tris[i].vertices) != tuple(f[i].tolist()) for i in picks):
        return None
    return f


def instanced_sources(obj):
    """Session ids of the objects ``obj`` may instance (vertex / face instancing's
    children and theirs, particle systems' instance objects and collections), or
    None where that cannot be told from settings (geometry nodes)."""
    if any(m.type == "NODES" for m in obj.modifiers):
        return None
    out = set()
    if obj.instance_type in {"VERTS", "FACES"}:
        out.update(ident(c) for c in obj.children_recursive)
    for ps in obj.particle_systems:
        s = ps.settings
        if s.instance_object is not None:
            out.add(ident(s.instance_object))
        if s.instance_collection is not None:
            out.update(ident(o) for o in s.instance_collection.all_objects)
    return out


def is_instancer(obj) -> bool:
    return obj.instance_type == "COLLECTION" and obj.instance_collection is not None


def may_instance(obj):
    """Whether ``obj`` can bring instances (vertex / face instancing, particles, geometry nodes)."""
    mods = obj.modifiers
    return obj.instance_type in {"VERTS", "FACES"} or len(obj.particle_systems) > 0 \
        or (len(mods) > 0 and any(m.type == "NODES" for m in mods))


def kind(obj) -> Kind | None:
    """The :class:`Kind` of ``obj``, or None: it takes no part (it occludes nothing)."""
    if obj.type in GEOMETRY_TYPES:
        if obj.display_type not in SOLID_DISPLAY or obj.show_in_front:
            return None                   # wire or bounds occlude nothing; "in front" is drawn over walls
        parent = obj.parent
        if parent is not None and parent.instance_type in {"VERTS", "FACES"}:
            return None                   # drawn only as the parent's instances
        return Kind.INSTANCER if may_instance(obj) else Kind.MESH
    if obj.type == "EMPTY" and is_instancer(obj):
        if obj.display_type not in SOLID_DISPLAY or obj.show_in_front:
            return None                   # its instances are drawn as it is (wire, bounds, in front)
        return Kind.COLLECTION
    return None


_POINTERS = {}     # modifier type -> its properties that point to objects, collections or textures


def _object_pointers(mod):
    """Whether a modifier reads another datablock (mirror object, array caps, ...)."""
    props = _POINTERS.get(mod.type)
    if props is None:
        props = _POINTERS[mod.type] = [
            p.identifier for p in mod.bl_rna.properties
            if p.type == "POINTER" and getattr(p.fixed_type, "identifier", "") in {"Object", "Collection", "Texture"}]
    return any(getattr(mod, p, None) is not None for p in props)


def _animated(idblock):
    ad = getattr(idblock, "animation_data", None)
    return ad is not None and (ad.action is not None or len(ad.drivers) > 0 or len(ad.nla_tracks) > 0)


def _data_animated(data) -> bool:
    return _animated(data) or _animated(getattr(data, "shape_keys", None))


def is_dynamic(obj, memo: dict | None = None) -> bool:
    """Whether ``obj``'s evaluated state can change without an edit (animation,
    drivers, constraints, physics, particles, instancing, geometry nodes,
    modifiers that read other objects, bone or vertex parents, a dynamic parent):
    such an object is never hidden, since Blender stops evaluating what is hidden.
    ``memo``: whether each object data is animated (shared meshes are asked once)."""
    seen = 0
    while obj is not None and seen < 64:      # parent chains: a few levels
        if _animated(obj) or len(obj.constraints) or obj.rigid_body is not None \
                or obj.rigid_body_constraint is not None or len(obj.particle_systems) \
                or obj.instance_type in {"VERTS", "FACES"}:
            return True
        data = obj.data
        if data is not None:
            if memo is None:
                animated = _data_animated(data)
            else:
                animated = memo.get(data)
                if animated is None:
                    animated = memo[data] = _data_animated(data)
            if animated:
                return True
        for m in obj.modifiers:
            if m.type not in STATIC_MODIFIERS or _object_pointers(m):
                return True
        if obj.parent is not None and obj.parent_type not in {"OBJECT"}:
            return True
        obj = obj.parent
        seen += 1
    return False


def bulk_matrices(collection, prop: str) -> np.ndarray:
    """``(n, 4, 4) float64`` of a matrix property over a whole collection, one ``foreach_get``.

    Blender stores matrices column-major and in float32, so the float32 read is exact.
    """
    flat = np.empty(len(collection) * 16, dtype=np.float32)
    collection.foreach_get(prop, flat)
    return flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)


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
    layer = view_layer.objects
    rest = np.flatnonzero(~np.isin(identity.uids(layer), held))
    if not len(rest):
        return []
    items = layer.values()                        # one list; indexing the collection is O(i)
    return [o for o in (items[i] for i in rest)
            if (o.type in DRAWN_TYPES or is_instancer(o)) and o.visible_get()]


class NoView(Enum):
    """:func:`drawn`'s ``space`` for no 3D view at all: the view layer's own visibility."""

    BASE = "base"


def drawn(view_layer, uids_all: np.ndarray, space=None) -> np.ndarray:
    """``(n,) bool`` over ``view_layer.objects``: what Blender draws in 3D view ``space``
    (None: the context's 3D view, if any; :attr:`NoView.BASE`: no view, the view layer's eye,
    collection and monitor flags), as ``visible_get(viewport=space)`` tells one object at
    a time, in bulk: ``context.visible_objects`` in that view's context (one list, a
    fraction of a ``visible_get`` per object)."""
    context = bpy.context
    found = None
    if space is NoView.BASE:                         # no view: the view layer's own visibility
        shown = None
        if context.view_layer == view_layer:
            if context.area is None:
                shown = context.visible_objects
            else:
                try:
                    with context.temp_override(area=None, region=None):
                        shown = bpy.context.visible_objects
                except (TypeError, RuntimeError):    # no override without a view: one by one
                    shown = None
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
        uids_all = identity.uids(layer)
        stale_all = identity.layer_flags("occ_culled", uids_all, layer)     # hidden everywhere: not evaluated
        culled_all = stale_all | identity.layer_flags(identity.VIEW_RECORD, uids_all, layer)
        info = extractor.info
        no_instances = filters_geometry(space)
        # drawn now, or hidden by the add-on: only those can take part (what else the user
        # or the view hides is not looked at one by one)
        shown = drawn(view_layer, uids_all, space)
        # hidden in one view only, what the user shows is what the view layer shows
        base = drawn(view_layer, uids_all, NoView.BASE) if (culled_all & ~stale_all).any() else None
        items = layer.values()                        # one list; indexing the collection is O(i)
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
        kinds = [KINDS[c] for c in codes.tolist()]
        objects = [items[i] for i in index]
        index = np.array(index, dtype=np.int64)
        self.culled = culled_all[index]
        self.stale = stale_all[index]
        m = bulk_matrices(layer, "matrix_world")[index] if len(index) else np.zeros((0, 4, 4))
        hidden = np.flatnonzero(stale_all[index])
        if len(hidden):                               # stale matrix_world: rebuilt from matrix_basis
            m[hidden] = bulk_matrices(layer, "matrix_basis")[index[hidden]]
            for k in hidden:
                if info[int(uids_all[index[k]])].parented:   # through the parent chain
                    m[k] = world_matrix(objects[k])
        if depsgraph is not None:
            extractor.fresh_matrices(objects, uids_all[index], ~stale_all[index], m, depsgraph, every)
        finite = np.all(np.isfinite(m), axis=(1, 2))
        self.bad = [objects[k].name for k in np.flatnonzero(~finite)]
        keep = np.flatnonzero(finite)
        self.objects = [objects[k] for k in keep]
        self.kinds = [kinds[k] for k in keep]
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
        self.stale_originals = set()  # uids whose original matrix_world lags their evaluated one

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
        for uid, (v, f) in _instanced_geometry(depsgraph, fresh).items():
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


def _mesh_fingerprint(mesh, memo):
    """Sizes and checksums of a mesh's vertex positions and of its faces' corners (once
    per mesh: ``memo``): an edit of the faces alone (edges rotated, faces deleted and
    others made of the same vertices) changes what the mesh covers as much as a move
    of its vertices."""
    key = ("fp", ident(mesh))
    hit = memo.get(key)
    if hit is None:
        co = positions(mesh)
        hit = memo[key] = (len(mesh.vertices), len(mesh.polygons), zlib.crc32(co),
                           zlib.crc32(_corner_vertices(mesh)), _shape_keys_fingerprint(mesh))
    return hit


def _shape_keys_fingerprint(mesh):
    """Each shape key's settings and a checksum of its positions (a key's value set by
    hand while the object is hidden moves its vertices as much as an edit)."""
    keys = mesh.shape_keys
    if keys is None:
        return ()
    out = [keys.use_relative, keys.eval_time]
    for kb in keys.key_blocks:
        co = np.empty(len(kb.data) * 3, dtype=np.float32)
        kb.data.foreach_get("co", co)
        out.append((kb.value, kb.mute, kb.slider_min, kb.slider_max, kb.relative_key.name,
                    kb.vertex_group, zlib.crc32(co)))
    return tuple(out)


def _modifiers_fingerprint(obj):
    """Each modifier's type and every setting it has (its RNA properties and, for
    geometry nodes, its inputs): a modifier edited while the object is hidden changes
    the geometry as much as a vertex moved."""
    mods = obj.modifiers            # most objects have none: no generator made (50,000 a pass)
    return tuple([_settings(m) for m in mods]) if len(mods) else ()


def _settings(m) -> tuple:
    """A comparable value of one modifier's settings."""
    out = [m.type]
    for p in m.bl_rna.properties:
        if p.identifier in ("rna_type", "name", "is_active", "show_expanded", "persistent_uid") \
                or p.type == "COLLECTION":
            continue
        out.append(_value(getattr(m, p.identifier, None)))
    if m.type == "NODES":                               # its inputs: ID properties (before 5.2)
        try:
            out.extend((k, _value(m[k])) for k in m.keys())
        except TypeError:                               # (5.2: not ID properties; a geometry-nodes
            pass                                        # object is dynamic, never hidden, anyway)
    return tuple(out)


def _value(v):
    """A hashable stand-in for an RNA or ID-property value (datablocks by identity)."""
    if isinstance(v, bpy.types.ID):
        return ("id", ident(v))
    if isinstance(v, (bool, int, float, str)) or v is None:
        return v
    try:
        return tuple(_value(x) for x in v)
    except TypeError:
        return repr(type(v))


def fingerprint(obj, k: Kind, memo: dict) -> tuple | None:
    """What the geometry of ``obj`` is read from, as a comparable value: its mesh
    (sizes and a checksum of its vertices), its display, its modifiers; for a
    collection instance, its members' and their placement.  None where it cannot
    be told cheaply (curves, text, metaballs): such an object is shown again to
    be read.  Modifier settings are not in it: edited while hidden, they are
    seen once the object is shown."""
    base = (k, obj.display_type, obj.show_in_front, obj.instance_type)
    if k is Kind.COLLECTION:
        parts = [base]
        for m in obj.instance_collection.all_objects:
            if m.type != "MESH":
                return None
            parts.append((ident(m), m.display_type, _modifiers_fingerprint(m),
                          _mesh_fingerprint(m.data, memo), tuple(map(tuple, m.matrix_basis))))
        return tuple(parts)
    if obj.type != "MESH":
        return None
    return base + (ident(obj.data), _modifiers_fingerprint(obj), _mesh_fingerprint(obj.data, memo))


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


def _instanced_geometry(depsgraph, instancers):
    """World-space geometry of the instances of instancers ``{uid: obj}``: ``{uid: (v, f)}``.
    Instanced objects displayed as wire or bounds are left out (they occlude nothing)."""
    if not instancers:
        return {}
    parts = {uid: [] for uid in instancers}
    # No mesh of an instance is read while iterating: its object is a temporary, and
    # reading its mesh there (to_mesh, or the mesh itself) made Blender 4.2 crash in the
    # iteration in 4 runs of 6 of workflow seed 5020 (about 1 in 9 without the reads:
    # 4.2's iterator crashes there on its own now and then).  An instance of a real
    # object is read once from that object's own evaluated copy, after the iteration
    # (once however many particles show it); geometry an instancer made itself
    # (geometry nodes' own meshes) is read from its evaluated geometry
    # (:func:`_made_geometry`); where that cannot be read (Blender 4.2 has no such API)
    # the instancer is UNREAD: kept visible, never an occluder.
    sources = {}                                     # source uid -> (original, {owner: [matrix]})
    unknown = set()
    for inst in depsgraph.object_instances:
        if not inst.is_instance or inst.parent is None:
            continue
        instancer = inst.parent.original
        owner = ident(instancer)
        ob = inst.object
        if owner not in parts or ob.type not in GEOMETRY_TYPES or ob.display_type not in SOLID_DISPLAY:
            continue
        m = np.array(inst.matrix_world, dtype=np.float64)
        source = ob.original
        if source is not None and source != instancer:
            sources.setdefault(ident(source), (source, {}))[1].setdefault(owner, []).append(m)
        elif not MADE_READABLE:
            unknown.add(owner)                       # geometry it made, not to be read here
    for source, uses in sources.values():
        evaluated = source.evaluated_get(depsgraph)
        if not evaluated.is_evaluated:
            continue                                 # not in this depsgraph: what it draws is unknown
        v, f = mesh_arrays(evaluated)
        for owner, mats in uses.items():
            parts[owner].append(_placed(v, f, np.array(mats)))
    for uid, obj in instancers.items():
        if not MADE_READABLE or obj.type == "EMPTY":   # an empty makes no geometry (5.2 refuses to say)
            continue
        evaluated = obj.evaluated_get(depsgraph)
        if evaluated.display_type in SOLID_DISPLAY:
            try:
                parts[uid] += _made_geometry(evaluated)
            except (TypeError, RuntimeError, _Unread):   # Blender cannot give all of it: unread, kept visible
                unknown.add(uid)
    out = {uid: UNREAD for uid in unknown}
    for uid, pieces in parts.items():
        if uid in out:
            continue
        base, vs, fs = 0, [], []
        for v, f in pieces:
            vs.append(v)
            fs.append(f.astype(np.int64) + base)
            base += len(v)
        out[uid] = (np.concatenate(vs), np.concatenate(fs)) if pieces else _EMPTY
    return out


MADE_DEPTH = 8          # instances of instances an instancer's own geometry is followed through
# Whether Blender gives an instancer's own geometry after evaluation (4.3 on); before
# (4.2), reading those meshes crashed Blender (see _instanced_geometry): such an
# instancer's geometry is UNREAD (a NaN vertex), which the engine keeps visible and
# never draws as an occluder (core.Scene.invalid): never hidden, never reported never visible.
MADE_READABLE = hasattr(bpy.types.Object, "evaluated_geometry")
UNREAD = (np.full((1, 3), np.nan, dtype=np.float32), np.zeros((1, 3), dtype=np.int32))


class _Unread(Exception):
    """Part of what an instancer made cannot be read: the instancer is UNREAD."""


def _placed(v, f, mats):
    """One mesh ``(v, f)`` placed by each matrix of ``mats`` ``(k, 4, 4)``, as one piece:
    world vertices ``(k nv, 3)`` and faces ``(k nf, 3) int64`` (in bulk: a hair system
    places one mesh thousands of times)."""
    k, nv = len(mats), len(v)
    world = np.einsum("kij,nj->kni", mats[:, :3, :3], v) + mats[:, None, :3, 3]
    faces = f[None].astype(np.int64) + (np.arange(k, dtype=np.int64) * nv)[:, None, None]
    return world.reshape(-1, 3), faces.reshape(-1, 3)


def _made_geometry(evaluated):
    """World-space ``[(v, f)]`` of the meshes geometry nodes made and instanced on the
    evaluated object ``evaluated`` (its instances of other objects and collections are
    the depsgraph iteration's), read from its evaluated geometry after the evaluation,
    each mesh once however often it is instanced (``Object.evaluated_geometry``, Blender
    4.3 on).  Raises :class:`_Unread` where instances carry no transforms or nest
    deeper than :data:`MADE_DEPTH`."""
    out = []
    stack = [(evaluated.evaluated_geometry(), np.array(evaluated.matrix_world, dtype=np.float64), 0)]
    while stack:
        geometry, world, depth = stack.pop()
        points = geometry.instances_pointcloud()
        if points is None or not len(points.points):
            continue
        index, transform = points.attributes.get(".reference_index"), points.attributes.get("instance_transform")
        if index is None or transform is None:
            raise _Unread("instances without transforms")
        n = len(points.points)
        which = np.zeros(n, dtype=np.int32)
        index.data.foreach_get("value", which)
        t = np.zeros(n * 16, dtype=np.float32)
        transform.data.foreach_get("value", t)
        t = t.reshape(n, 4, 4).transpose(0, 2, 1).astype(np.float64)    # stored by columns
        for r, ref in enumerate(geometry.instance_references()):
            if not isinstance(ref, bpy.types.GeometrySet):
                continue                                      # an object or a collection: iterated
            at = np.flatnonzero(which == r)
            if not len(at):
                continue
            mats = world @ t[at]
            mesh = ref.mesh
            if mesh is not None:
                v, f = _read_mesh(mesh)
                if len(f):
                    out.append(_placed(v, f, mats))
            nested = ref.instances_pointcloud()
            if nested is not None and len(nested.points):     # instances inside: followed per placement
                if depth >= MADE_DEPTH:
                    raise _Unread("instances nested too deep")
                stack.extend((ref, m, depth + 1) for m in mats)
    return out


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
