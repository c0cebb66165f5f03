"""From Blender to the engine's arrays, through the evaluated depsgraph, in bulk.

Every visible mesh-like object (modifiers applied, curves and text as meshes)
becomes an object of :class:`core.Scene`; a collection instance becomes one
object carrying the instanced geometry; the collection tree (and object
parents) becomes the scene tree.  Objects that share an unmodified mesh share
it in the engine.

Each pass asks two questions of different cost:

- which objects take part (one ``visible_get`` per object) and where they are
  (one ``foreach_get`` of every world matrix): :meth:`Extractor.candidates`,
  :meth:`Extractor.matrices`, cheap, every pass;
- what they look like (``to_mesh`` + ``foreach_get`` per changed object):
  :meth:`Extractor.scene`, only when the set of objects or some geometry
  changed.  Geometry is cached per object; the depsgraph handler marks what
  changed (:meth:`Extractor.mark`), and only that is read again.
"""

import numpy as np

from ..core import OccError, Scene

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
_EMPTY = (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))


def mesh_arrays(obj_eval):
    """Local vertices ``(v, 3) float64`` and triangles ``(f, 3) int64`` of an evaluated object."""
    mesh = obj_eval.to_mesh()
    if mesh is None:                     # e.g. an empty text object
        obj_eval.to_mesh_clear()
        return _EMPTY
    try:
        mesh.calc_loop_triangles()
        v = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", v)
        f = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", f)
    finally:
        obj_eval.to_mesh_clear()
    return v.reshape(-1, 3).astype(np.float64), f.reshape(-1, 3).astype(np.int64)


def is_instancer(obj):
    return obj.instance_type == "COLLECTION" and obj.instance_collection is not None


def _bulk_matrices(collection, prop):
    """``(n, 4, 4) float64`` of a matrix property over a whole collection, one ``foreach_get``.

    Blender stores matrices column-major and in float32, so the float32 read is exact.
    """
    flat = np.empty(len(collection) * 16, dtype=np.float32)
    collection.foreach_get(prop, flat)
    return flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)


def world_matrix(obj):
    """World matrix ``(4, 4)``.  An object the add-on hid is not evaluated by the
    depsgraph (its ``matrix_world`` goes stale), so its matrix is rebuilt from
    the parent chain and ``matrix_basis`` (constraints and drivers on hidden
    objects are not followed)."""
    if not obj.occ_culled:
        return np.array(obj.matrix_world, dtype=np.float64)
    m = np.array(obj.matrix_basis, dtype=np.float64)
    if obj.parent is not None:
        m = world_matrix(obj.parent) @ np.array(obj.matrix_parent_inverse, dtype=np.float64) @ m
    return m


class Candidates:
    """The objects that take part in a pass, in view-layer order.

    objects: bpy objects; names: their names (a tuple, compared between
    passes); layer_index: ``(n,) int64`` position of each in
    ``view_layer.objects``; culled: ``(n,) bool`` hidden by the add-on now.
    """

    def __init__(self, view_layer):
        self.view_layer = view_layer
        objects, index, culled = [], [], []
        for i, o in enumerate(view_layer.objects):    # one visible_get per object; no bulk form exists
            if o.type not in GEOMETRY_TYPES and not is_instancer(o):
                continue
            ours = o.occ_culled
            if ours or o.visible_get():               # visible to the user now, or hidden by us
                objects.append(o)
                index.append(i)
                culled.append(ours)
        self.objects = objects
        self.names = tuple(o.name for o in objects)
        self.layer_index = np.array(index, dtype=np.int64)
        self.culled = np.array(culled, dtype=bool)

    def __len__(self):
        return len(self.objects)


class Extractor:
    """Keeps the last extraction and refreshes only what changed."""

    def __init__(self):
        self.cache = {}          # object name -> (mesh key, vertices, faces)
        self.dirty = set()       # objects whose geometry changed
        self.touched = set()     # objects whose geometry or transform changed (instanced collections)

    def mark(self, geometry=(), transform=()):
        """Record depsgraph updates: names whose geometry changed, and names that moved."""
        self.dirty.update(geometry)
        self.touched.update(geometry)
        self.touched.update(transform)

    def candidates(self, context):
        return Candidates(context.view_layer)

    def needs_geometry(self, cand):
        """Whether :meth:`scene` must read geometry again for these candidates."""
        if self.dirty.intersection(cand.names):
            return True
        if self.touched:
            for o in cand.objects:
                if is_instancer(o) and not o.occ_culled and self._instance_stale(o):
                    return True
        return False

    def forget_changes(self):
        """The current scene is up to date: changes seen so far are consumed."""
        self.dirty.clear()
        self.touched.clear()

    def matrices(self, cand, kept):
        """World matrices ``(k, 4, 4) float64`` of candidates ``kept`` (indices), in bulk."""
        m = _bulk_matrices(cand.view_layer.objects, "matrix_world")[cand.layer_index[kept]]
        culled = np.flatnonzero(cand.culled[kept])
        if len(culled):                                # stale matrix_world: rebuild from matrix_basis
            basis = _bulk_matrices(cand.view_layer.objects, "matrix_basis")[cand.layer_index[kept]]
            for k in culled:
                obj = cand.objects[kept[k]]
                m[k] = basis[k] if obj.parent is None else world_matrix(obj)
        return m

    def scene(self, context, cand):
        """``(core.Scene, kept)``: the engine's scene of the candidates with triangles,
        ``kept`` their indices into ``cand``."""
        depsgraph = context.evaluated_depsgraph_get()
        fresh = {o.name: o for o in cand.objects if is_instancer(o) and not o.occ_culled
                 and self._instance_stale(o)}
        for name, (v, f) in _instanced_geometry(depsgraph, fresh).items():
            o = fresh[name]
            inv = _inverse(np.array(o.matrix_world, dtype=np.float64))   # instancer-local: a move is a matrix
            key = ("instance", name, _members(o.instance_collection))
            self.cache[name] = (key, v @ inv[:3, :3].T + inv[:3, 3], f)
        names, meshes, mesh_of, kept = [], [], [], []
        mesh_index, read = {}, {}
        for i, obj in enumerate(cand.objects):         # once per object, bulk inside
            entry = self._geometry(obj, depsgraph, read)
            if entry is None or len(entry[2]) == 0:
                continue
            key, v, f = entry
            if key not in mesh_index:
                mesh_index[key] = len(meshes)
                meshes.append((v, f))
            names.append(obj.name)
            mesh_of.append(mesh_index[key])
            kept.append(i)
        self.forget_changes()
        if not names:
            raise OccError("nothing to cull: the view layer has no visible mesh objects")
        kept = np.array(kept, dtype=np.int64)
        tree_parent, tree_object = _tree(context.scene, [cand.objects[i] for i in kept])
        scene = Scene.from_arrays(names, meshes, np.array(mesh_of), self.matrices(cand, kept),
                                  tree_parent, tree_object)
        return scene, kept

    def _instance_stale(self, obj):
        hit = self.cache.get(obj.name)
        if hit is None:
            return True
        members = _members(obj.instance_collection)
        return hit[0][2] != members or bool(self.touched.intersection(members))

    def _geometry(self, obj, depsgraph, read):
        """``(key, v, f)`` from the cache when still valid, else from the depsgraph
        (a shared mesh once per pass: ``read``); None for an object the add-on hid
        that was never extracted."""
        hit = self.cache.get(obj.name)
        if is_instancer(obj) or obj.occ_culled:        # instancers: read above; hidden: not evaluated
            return hit
        shared = obj.type == "MESH" and not obj.modifiers and obj.data.users > 1
        key = ("mesh", obj.data.name) if shared else ("object", obj.name)
        if hit is not None and hit[0] == key and obj.name not in self.dirty:
            return hit
        if key not in read:
            read[key] = mesh_arrays(obj.evaluated_get(depsgraph))
        v, f = read[key]
        self.cache[obj.name] = (key, v, f)
        return key, v, f


def _inverse(m):
    """Inverse of a world matrix; for a singular one (a scale of 0) the pseudo-inverse,
    which still maps the instance's (flat) world geometry back exactly."""
    try:
        return np.linalg.inv(m)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(m)


def _members(collection):
    """Names of the objects an instanced collection brings, as a sorted tuple."""
    return tuple(sorted(o.name for o in collection.all_objects))


def _instanced_geometry(depsgraph, instancers):
    """World-space geometry of collection instancers ``{name: obj}``: ``{name: (v, f)}``."""
    if not instancers:
        return {}
    parts = {name: [] for name in instancers}
    for inst in depsgraph.object_instances:
        if not inst.is_instance or inst.parent is None:
            continue
        owner = inst.parent.original.name
        if owner not in parts or inst.object.type not in GEOMETRY_TYPES:
            continue
        v, f = mesh_arrays(inst.object)
        m = np.array(inst.matrix_world, dtype=np.float64)
        parts[owner].append((v @ m[:3, :3].T + m[:3, 3], f))
    out = {}
    for name, pieces in parts.items():
        base, vs, fs = 0, [], []
        for v, f in pieces:
            vs.append(v)
            fs.append(f + base)
            base += len(v)
        out[name] = (np.concatenate(vs), np.concatenate(fs)) if pieces else _EMPTY
    return out


def _tree(scene, objects):
    """Scene tree over collections (groups) and objects (parents kept)."""
    index = {o.name: i for i, o in enumerate(objects)}
    parent, carried, node_of = [], [], {}

    def add(obj_index, parent_node):
        parent.append(parent_node)
        carried.append(obj_index)
        return len(parent) - 1

    def walk(coll, parent_node):                      # collections: a handful, recursion ok
        node = add(-1, parent_node)
        for obj in coll.objects:
            if obj.name in index and obj.name not in node_of:
                node_of[obj.name] = add(index[obj.name], node)
        for child in coll.children:
            walk(child, node)

    walk(scene.collection, -1)
    parent = np.array(parent, dtype=np.int64)
    carried = np.array(carried, dtype=np.int64)
    for obj in objects:                               # object parenting refines the tree
        if obj.parent is not None and obj.parent.name in node_of and obj.name in node_of:
            parent[node_of[obj.name]] = node_of[obj.parent.name]
    return parent, carried
