"""From Blender to the engine's arrays, through the evaluated depsgraph, in bulk.

Every visible mesh-like object (modifiers applied, curves and text as meshes)
becomes an object of :class:`core.Scene`; a collection instance becomes one
object carrying the instanced geometry; the collection tree (and object
parents) becomes the scene tree.  Objects that share an unmodified mesh share
it in the engine.  The extraction is cached per object and redone only for the
objects the depsgraph reports as changed.
"""

import numpy as np

from ..core import OccError, Scene


def mesh_arrays(obj_eval):
    """Local vertices ``(v, 3) float64`` and triangles ``(f, 3) int64`` of an evaluated object."""
    mesh = obj_eval.to_mesh()
    try:
        mesh.calc_loop_triangles()
        v = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", v)
        f = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", f)
    finally:
        obj_eval.to_mesh_clear()
    return v.reshape(-1, 3).astype(np.float64), f.reshape(-1, 3).astype(np.int64)


GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}


def is_candidate(obj):
    """Takes part in culling: visible to the user now, or hidden by us."""
    return obj.occ_culled or obj.visible_get()


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


class Extractor:
    """Keeps the last extraction and refreshes only what changed."""

    def __init__(self):
        self.cache = {}          # object name -> (mesh key, vertices, faces)
        self.dirty = set()
        self.all_dirty = True

    def mark(self, names=None):
        if names is None:
            self.all_dirty = True
        else:
            self.dirty.update(names)

    def scene(self, context):
        """``(core.Scene, [bpy objects])`` of the candidates in the view layer."""
        depsgraph = context.evaluated_depsgraph_get()
        objects = [o for o in context.view_layer.objects if is_candidate(o)]
        instancers = [o for o in objects if o.instance_type == "COLLECTION" and o.instance_collection]
        fresh = _instanced_geometry(depsgraph, {o.name for o in instancers if not o.occ_culled})
        for o in instancers:                              # instancer-local, so moving it is a matrix
            if o.name in fresh:
                v, f = fresh[o.name]
                inv = np.linalg.inv(np.array(o.matrix_world, dtype=np.float64))
                self.cache[o.name] = (("instance", o.name), v @ inv[:3, :3].T + inv[:3, 3], f)
        names, meshes, mesh_of, matrices, kept = [], [], [], [], []
        mesh_index = {}
        for obj in objects:                               # once per object, bulk inside
            if obj in instancers or obj.type in GEOMETRY_TYPES:
                entry = self._geometry(obj, depsgraph)
                if entry is None:
                    continue
                key, v, f = entry
                matrix = world_matrix(obj)
            else:
                continue
            if len(f) == 0:
                continue
            if key not in mesh_index:
                mesh_index[key] = len(meshes)
                meshes.append((v, f))
            names.append(obj.name)
            mesh_of.append(mesh_index[key])
            matrices.append(matrix)
            kept.append(obj)
        self.dirty.clear()
        self.all_dirty = False
        if not names:
            raise OccError("nothing to cull: the view layer has no visible mesh objects")
        tree_parent, tree_object = _tree(context.scene, kept)
        scene = Scene.from_arrays(names, meshes, np.array(mesh_of), np.array(matrices),
                                  tree_parent, tree_object)
        return scene, kept

    def _geometry(self, obj, depsgraph):
        """``(key, v, f)`` from the cache when still valid, else from the depsgraph;
        None for an object the add-on hid that was never extracted."""
        hit = self.cache.get(obj.name)
        if obj.instance_type == "COLLECTION" and obj.instance_collection:
            return hit
        if obj.occ_culled:                    # not evaluated while hidden: the last extraction
            return hit
        shared = obj.type == "MESH" and not obj.modifiers and obj.data.users > 1
        key = ("mesh", obj.data.name) if shared else ("object", obj.name)
        if hit is not None and hit[0] == key and not self.all_dirty and obj.name not in self.dirty:
            return hit
        v, f = mesh_arrays(obj.evaluated_get(depsgraph))
        self.cache[obj.name] = (key, v, f)
        return key, v, f


def _instanced_geometry(depsgraph, instancers):
    """World-space geometry of each collection instancer: ``{name: (v, f)}``."""
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
        out[name] = ((np.concatenate(vs), np.concatenate(fs)) if pieces
                     else (np.zeros((0, 3)), np.zeros((0, 3), np.int64)))
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
