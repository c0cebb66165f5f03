"""Draw units: what a hierarchy leaf draws -- a whole object, or a chunk of its mesh.

A heavy mesh is cut into chunks by reordering its faces (once, on upload; the
user's mesh is untouched) so that every chunk is a contiguous index range; no
triangle is split.  Chunking is per mesh, so every object that shares the mesh
shares its chunks, each chunk box moved by the object's matrix.

Arrays (u units):
- ``object``       ``(u,) int64`` object the unit belongs to;
- ``first``        ``(u,) int64`` first triangle of the unit in its mesh's face order;
- ``count``        ``(u,) int64`` triangles in the unit;
- ``local_bounds`` ``(u, 2, 3) float64`` box in the mesh's local coordinates.
"""

from dataclasses import dataclass

import numpy as np

from .bounds import transform_boxes
from .subdivision import ItemBoxes


@dataclass(eq=False)
class Units:
    object: np.ndarray
    first: np.ndarray
    count: np.ndarray
    local_bounds: np.ndarray
    face_order: list          # per mesh: (f,) int32 (int64 beyond 2**31 faces) face permutation, or None
    trees: list               # per object: chunk Tree over its units, or None
    of_object: list           # per object: (k,) its units

    def __len__(self):
        return len(self.object)

    def world_bounds(self, matrices):
        """World boxes of the units for object matrices ``(n, 4, 4)``."""
        if not len(self):
            return np.zeros((0, 2, 3))
        return transform_boxes(self.local_bounds, matrices[self.object])


BLOCK = 1 << 18      # triangles (or vertices) per step of triangle_bounds: temporaries of a few MB


def _outward(exact):
    """float32 copies of float64 coordinates rounded down and up: ``(lo, hi)``."""
    near = exact.astype(np.float32)
    wide = near.astype(np.float64)
    if np.array_equal(wide, exact):              # float32 data (Blender's, glTF's): exact as it is
        return near, near
    down = np.where(wide > exact, np.nextafter(near, np.float32(-np.inf)), near)
    up = np.where(wide < exact, np.nextafter(near, np.float32(np.inf)), near)
    return down, up


def triangle_bounds(vertices, faces):
    """Boxes of triangles as axis-major float32 corner arrays: ``(v, 3)``, ``(f, 3)`` ->
    ``lo, hi`` ``(3, f) float32`` (a quarter of the float64 ``(f, 2, 3)`` boxes'
    memory), built in blocks of ``BLOCK`` triangles with temporaries of a few MB.

    Conservative: every vertex coordinate is rounded outward to float32 (down for
    ``lo``, up for ``hi``), so each box contains its float64 triangle.  float32
    vertices (Blender's) are exact as they are and are gathered from directly, with
    no copy of them; others go through two outward-rounded float32 copies ``(v, 3)``.
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.dtype == np.float32:
        down = up = v
    else:
        down = np.empty((len(v), 3), dtype=np.float32)
        up = np.empty((len(v), 3), dtype=np.float32)
        with np.errstate(over="ignore", invalid="ignore"):     # beyond float32's range: inf, refused by the builder
            for s in range(0, len(v), BLOCK):
                down[s:s + BLOCK], up[s:s + BLOCK] = _outward(v[s:s + BLOCK])
    lo = np.empty((3, len(f)), dtype=np.float32)
    hi = np.empty((3, len(f)), dtype=np.float32)
    for s in range(0, len(f), BLOCK):
        corner = f[s:s + BLOCK].T.ravel()            # (3b,) vertex indices, corner-major
        g = np.take(down, corner, axis=0).reshape(3, -1, 3)      # (corner, triangle, axis)
        lo[:, s:s + BLOCK] = np.minimum(np.minimum(g[0], g[1]), g[2]).T
        if up is not down:
            g = np.take(up, corner, axis=0).reshape(3, -1, 3)
        hi[:, s:s + BLOCK] = np.maximum(np.maximum(g[0], g[1]), g[2]).T
    return lo, hi


def whole_objects(scene):
    """One unit per object: unit i draws object i."""
    n = len(scene)
    tri = scene.triangle_counts
    return Units(object=np.arange(n, dtype=np.int64), first=np.zeros(n, dtype=np.int64),
                 count=tri.astype(np.int64), local_bounds=scene.mesh_bounds[scene.mesh_of],
                 face_order=[None] * len(scene.meshes), trees=[None] * n,
                 of_object=[np.array([i]) for i in range(n)])


class ChunkCache:
    """Chunkings of meshes kept between builds: a mesh whose vertex and face arrays
    are the very same objects as last time is not cut again (the add-on rebuilds
    the engine after an edit; only the edited meshes are re-chunked).

    ``hits`` and ``misses`` count the meshes of the last build.
    """

    def __init__(self):
        self._entries, self._used = {}, {}
        self.hits = self.misses = 0

    def start(self):
        self._used, self.hits, self.misses = {}, 0, 0

    def get(self, v, f, make):
        key = (id(v), id(f))
        entry = self._entries.get(key)
        if entry is not None and entry[0] is v and entry[1] is f:     # ids alone can be reused
            self.hits += 1
        else:
            entry = (v, f, make())
            self.misses += 1
        self._used[key] = entry
        return entry[2]

    def finish(self):
        """Keep only the meshes of this build."""
        self._entries = self._used


def _chunk_mesh(v, f, build_tree):
    """(face order, chunk first, chunk count, chunk local boxes, chunk tree) of one mesh.

    The triangles' boxes are float32 corner arrays that the build reorders in
    place (:class:`core.subdivision.ItemBoxes`); a chunk's box is the union of its
    triangles' outward-rounded boxes, so it contains the chunk.
    """
    items = ItemBoxes(*triangle_bounds(v, f))
    tree = build_tree(items)
    owners = np.flatnonzero(tree.item_count > 0)
    first, count = tree.item_start[owners], tree.item_count[owners]
    # the owned ranges tile the item order: reduce them in order of their starts
    by_start = np.argsort(first, kind="stable")
    lo = np.empty((len(owners), 3))
    hi = np.empty((len(owners), 3))
    lo[by_start] = np.minimum.reduceat(items.lo, first[by_start], axis=1).T
    hi[by_start] = np.maximum.reduceat(items.hi, first[by_start], axis=1).T
    # item i of the chunk tree (as the hierarchy sees it) is chunk i; the face order,
    # kept as long as the mesh is, in 4 bytes a triangle where they suffice
    order = tree.order.astype(np.int32, copy=False) if len(tree.order) < 2**31 else tree.order
    return order, first, count, np.stack([lo, hi], axis=1), _tree_over_chunks(tree, owners)


def chunked(scene, should_chunk, build_tree, cache=None):
    """Units with heavy meshes cut into chunks.

    should_chunk(mesh_index, triangles) -> bool decides per mesh;
    build_tree(triangle boxes) -> a :class:`core.subdivision.Tree` over the
    triangles, whose nodes that own triangles become the chunks; the boxes come
    as :class:`core.subdivision.ItemBoxes` (float32, reordered in place), which
    :func:`core.subdivision.build_tree` takes as it takes ``(f, 2, 3)`` arrays;
    cache: a :class:`ChunkCache` whose chunkings of unchanged meshes are reused
    (the caller keeps ``build_tree`` the same between builds that share it).
    """
    cache = cache if cache is not None else ChunkCache()
    cache.start()
    per_mesh = []          # (face order, chunk first, chunk count, chunk local boxes, chunk tree)
    for m, (v, f) in enumerate(scene.meshes):
        if len(f) == 0 or not should_chunk(m, len(f)):
            per_mesh.append(None)
            continue
        per_mesh.append(cache.get(v, f, lambda v=v, f=f: _chunk_mesh(v, f, build_tree)))
    cache.finish()
    # Per mesh, its units as rows of flat tables (one row for a mesh drawn whole);
    # per object, its mesh's rows -- gathered at once, no loop over objects.
    tri = np.array([len(f) for _, f in scene.meshes], dtype=np.int64)
    k = np.array([1 if pm is None else len(pm[1]) for pm in per_mesh], dtype=np.int64)
    row0 = np.cumsum(k) - k                                   # first row of each mesh
    first = np.concatenate([np.zeros(1, np.int64) if pm is None else pm[1] for pm in per_mesh] or [[]])
    count = np.concatenate([tri[m:m + 1] if pm is None else pm[2] for m, pm in enumerate(per_mesh)] or [[]])
    boxes = np.concatenate([scene.mesh_bounds[m][None] if pm is None else pm[3]
                            for m, pm in enumerate(per_mesh)] or [np.zeros((0, 2, 3))])
    per_object = k[scene.mesh_of]                             # units of each object
    total = int(per_object.sum())
    start = np.cumsum(per_object) - per_object                # its first unit
    rows = np.repeat(row0[scene.mesh_of] - start, per_object) + np.arange(total)
    obj = np.repeat(np.arange(len(scene.mesh_of)), per_object)
    tree_of_mesh = [None if pm is None else pm[4] for pm in per_mesh]
    return Units(object=obj.astype(np.int64), first=first[rows].astype(np.int64),
                 count=count[rows].astype(np.int64), local_bounds=boxes[rows].reshape(-1, 2, 3),
                 face_order=[None if pm is None else pm[0] for pm in per_mesh],
                 trees=[tree_of_mesh[m] for m in scene.mesh_of],
                 of_object=np.split(np.arange(total), start[1:]) if total else [])


def _tree_over_chunks(tree, owners):
    """The same tree with items renumbered as chunks: node ``owners[i]`` owns chunk i."""
    from copy import copy
    t = copy(tree)
    t.order = np.arange(len(owners), dtype=np.int64)
    start = np.zeros(len(tree.item_count), dtype=np.int64)
    count = np.zeros(len(tree.item_count), dtype=np.int64)
    start[owners] = np.arange(len(owners))
    count[owners] = 1
    t.item_start, t.item_count = start, count
    return t
