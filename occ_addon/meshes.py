"""An evaluated object's mesh read as Blender holds it: local vertices ``(v, 3) float32``
and triangles ``(f, 3) int32`` in bulk (:func:`mesh_arrays`), from the evaluated mesh
itself or from a ``to_mesh`` copy (:data:`SHARED_ARRAYS`), a large mesh's triangles
from Blender's own array (:data:`RAW_TRIANGLES`)."""

import ctypes

import bpy
import numpy as np

EMPTY = (np.zeros((0, 3), dtype=np.float32), np.zeros((0, 3), dtype=np.int32))   # no vertices, no triangles


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
# ``tools/bench/blender_scale.py --only grid --steps``: first cull's peak 1,405 MB above the
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
        return read_mesh(obj_eval.data)
    mesh = obj_eval.to_mesh()
    if mesh is None:                     # e.g. an empty text object
        obj_eval.to_mesh_clear()
        return EMPTY
    try:
        return read_mesh(mesh)
    finally:
        obj_eval.to_mesh_clear()


def read_mesh(mesh):
    """Vertices ``(v, 3) float32`` and triangles ``(f, 3) int32`` of a mesh (its loop
    triangles computed first)."""
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


def corner_vertices(mesh) -> np.ndarray:
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
    (``tools/bench/blender_scale.py --only grid --steps``).  Trusted only where the items are evenly spaced
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
    to_vertex = corner_vertices(mesh)
    if int(corners.min()) < 0 or int(corners.max()) >= len(to_vertex):
        return None
    f = np.empty((n, 3), dtype=np.int32)
    for a in range(0, n, 1 << 20):                    # in blocks: no index array of the whole
        np.take(to_vertex, corners[a:a + (1 << 20)], out=f[a:a + (1 << 20)])
    del to_vertex
    if any(tuple(tris[i].vertices) != tuple(f[i].tolist()) for i in picks):
        return None
    return f
