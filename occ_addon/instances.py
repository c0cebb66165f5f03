"""Instanced geometry as Blender draws it: the world-space meshes that collection
instances and vertex/face, particle and geometry-nodes instancers bring, read from
``depsgraph.object_instances`` and from an instancer's own evaluated geometry
(:func:`instanced_geometry`: one ``(v, f)`` per instancer, :data:`UNREAD` where Blender
cannot give it)."""

import bpy
import numpy as np

from .drawn import DRAWN_TYPES
from .identity import ident
from .kinds import GEOMETRY_TYPES, SOLID_DISPLAY
from .materials import see_through
from .meshes import EMPTY, mesh_arrays, read_mesh


def instanced_geometry(depsgraph, instancers, beyond: set | None = None):
    """World-space geometry of the instances of instancers ``{uid: obj}``: ``{uid: (v, f)}``.
    Instanced objects displayed as wire or bounds are left out (they occlude nothing), and
    so are point clouds, volumes and curves; ``beyond`` gets the instancers whose
    instances Blender draws beyond that geometry (they are seen wherever they are drawn)."""
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
        if owner not in parts:
            continue
        ob = inst.object
        if not isinstance(ob, bpy.types.Object):
            # Blender 4.2 hands over an ID that is no object after a script removed one that
            # geometry nodes instanced, and the next step of its iteration crashes (workflow
            # seed 7194; tools/repro/gn_deleted_object_crash.py): the iteration ends here, and what
            # every instancer draws is unknown (kept visible, never an occluder)
            unknown.update(parts)
            break
        if ob.type not in GEOMETRY_TYPES or ob.display_type not in SOLID_DISPLAY:
            if beyond is not None and ob.type in DRAWN_TYPES:
                beyond.add(owner)
            continue
        m = np.array(inst.matrix_world, dtype=np.float64)
        source = ob.original
        if source is not None and source != instancer:
            sources.setdefault(ident(source), (source, {}))[1].setdefault(owner, []).append(m)
        elif not MADE_READABLE:
            unknown.add(owner)                       # geometry it made, not to be read here
    for source, uses in sources.values():
        if see_through(source):                      # (its materials: read after the iteration, as meshes)
            if beyond is not None:
                beyond.update(uses)
            continue
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
        if evaluated.display_type in SOLID_DISPLAY and not see_through(evaluated):
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
        out[uid] = (np.concatenate(vs), np.concatenate(fs)) if pieces else EMPTY
    return out


MADE_DEPTH = 8          # instances of instances an instancer's own geometry is followed through
# Whether Blender gives an instancer's own geometry after evaluation (4.3 on); before
# (4.2), reading those meshes crashed Blender (see instanced_geometry): such an
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
                v, f = read_mesh(mesh)
                if len(f):
                    out.append(_placed(v, f, mats))
            nested = ref.instances_pointcloud()
            if nested is not None and len(nested.points):     # instances inside: followed per placement
                if depth >= MADE_DEPTH:
                    raise _Unread("instances nested too deep")
                stack.extend((ref, m, depth + 1) for m in mats)
    return out
