"""Scenes as plain arrays: objects, their (possibly shared) meshes, world matrices
and the scene tree.

An *object* is a scene-graph node that carries triangles; its name is the node
name.  Meshes are stored once and referenced by ``mesh_of``, so a mesh placed a
thousand times is uploaded once.  The tree (``tree_parent``, ``tree_object``)
is the scene's own grouping -- glTF nodes, Blender collections -- and is the
skeleton the hierarchy builder starts from.
"""

from dataclasses import dataclass, field

import numpy as np

from .bounds import transform_boxes
from .errors import OccError

# Dtypes kept as given (no whole-mesh widening copy): float32 vertices are what Blender
# and glTF hold, and every consumer (bounds, chunking, upload) is exact on them.
_VERTEX_DTYPES = (np.float32, np.float64)
_FACE_DTYPES = (np.int32, np.uint32, np.int64)


def _mesh_arrays(vertices, faces, label):
    v = np.asarray(vertices)
    v = np.ascontiguousarray(v, dtype=v.dtype if v.dtype in _VERTEX_DTYPES else np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise OccError(f"{label}: vertices must be (v, 3), got {v.shape}")
    if f.size == 0:
        f = np.zeros((0, 3), dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise OccError(f"{label}: faces must be (f, 3), got {f.shape}")
    if f.dtype not in _FACE_DTYPES:
        f = f.astype(np.int64)
    f = np.ascontiguousarray(f)
    # one pass: seen unsigned, a negative index is larger than any vertex count
    if len(f) and int(f.view(np.dtype(f.dtype.str.replace("i", "u"))).max()) >= len(v):
        raise OccError(f"{label}: face indices out of range 0..{len(v) - 1}")
    return v, f


@dataclass(eq=False)
class Scene:
    """Objects of a scene as arrays.

    names: n object names; meshes: unique meshes ``(vertices (v, 3) float64 or
    float32, faces (f, 3) int64, int32 or uint32)`` (kept in the dtype given);
    mesh_of: ``(n,) int64`` mesh of each object;
    matrices: ``(n, 4, 4) float64`` world matrices; tree_parent / tree_object:
    ``(t,) int64`` parent tree node (-1 for roots) and carried object (-1 for a
    pure group) of each tree node, every object at most once.
    """

    names: list
    meshes: list
    mesh_of: np.ndarray
    matrices: np.ndarray
    tree_parent: np.ndarray
    tree_object: np.ndarray
    mesh_bounds: np.ndarray = field(init=False)
    invalid: np.ndarray = field(init=False)
    mesh_valid: np.ndarray = field(init=False)
    _tri: np.ndarray = field(init=False, default=None, repr=False)
    _bounds_memo: tuple = field(init=False, default=None, repr=False)

    def __post_init__(self):
        n = len(self.names)
        self.mesh_of = np.asarray(self.mesh_of, dtype=np.int64).reshape(-1)
        self.matrices = np.asarray(self.matrices, dtype=np.float64).reshape(-1, 4, 4) if n else np.zeros((0, 4, 4))
        if len(self.mesh_of) != n or len(self.matrices) != n:
            raise OccError(f"{n} names but {len(self.mesh_of)} mesh indices and "
                           f"{len(self.matrices)} matrices")
        if n and (self.mesh_of.min() < 0 or self.mesh_of.max() >= len(self.meshes)):
            raise OccError(f"mesh_of must index the {len(self.meshes)} meshes")
        self.meshes = [_mesh_arrays(v, f, f"mesh {i}") for i, (v, f) in enumerate(self.meshes)]
        mb = np.zeros((len(self.meshes), 2, 3))
        mesh_ok = np.ones(len(self.meshes), dtype=bool)
        for i, (v, _) in enumerate(self.meshes):      # once per unique mesh
            if len(v) > 4096:                         # one column at a time: ~15x faster than axis=0
                mb[i] = [[v[:, k].min() for k in range(3)], [v[:, k].max() for k in range(3)]]
            elif len(v):
                mb[i] = v.min(axis=0), v.max(axis=0)
            mesh_ok[i] = np.isfinite(mb[i]).all()       # min/max carry any NaN or inf of v
        mb[~mesh_ok] = 0.0
        self.mesh_bounds = mb
        self.mesh_valid = mesh_ok
        # NaN or infinite values in an object's matrix or mesh: the object is kept
        # (the engine keeps it visible and never draws it as an occluder) rather
        # than failing the whole scene; see invalid_names.
        self.invalid = ~np.all(np.isfinite(self.matrices), axis=(1, 2))
        if n:
            self.invalid |= ~mesh_ok[self.mesh_of]
        self.tree_parent = np.asarray(self.tree_parent, dtype=np.int64).reshape(-1)
        self.tree_object = np.asarray(self.tree_object, dtype=np.int64).reshape(-1)
        t = len(self.tree_parent)
        if len(self.tree_object) != t:
            raise OccError("tree_parent and tree_object must have the same length")
        if t and (self.tree_parent.min() < -1 or self.tree_parent.max() >= t):
            raise OccError("tree_parent must hold tree node indices or -1")
        carried = self.tree_object[self.tree_object >= 0]
        if len(carried) and (carried.max() >= n or len(np.unique(carried)) != len(carried)):
            raise OccError("tree_object must name each object at most once")

    @classmethod
    def from_arrays(cls, names, meshes, mesh_of, matrices, tree_parent=None, tree_object=None):
        """Build a scene from arrays; without a tree, every object is a root."""
        names = [str(s) for s in names]
        if tree_parent is None:
            tree_parent = np.full(len(names), -1, dtype=np.int64)
            tree_object = np.arange(len(names), dtype=np.int64)
        elif tree_object is None:
            raise OccError("tree_parent given without tree_object")
        return cls(names, list(meshes), mesh_of, matrices, tree_parent, tree_object)

    def __len__(self):
        return len(self.names)

    @property
    def invalid_names(self):
        """Names of the objects with NaN or infinite values in their matrix or mesh."""
        return [self.names[i] for i in np.flatnonzero(self.invalid)]

    @property
    def triangle_counts(self):
        """Triangles of each object, ``(n,) int64`` (meshes never change, so computed once)."""
        if self._tri is None:
            per_mesh = np.array([len(f) for _, f in self.meshes], dtype=np.int64)
            self._tri = per_mesh[self.mesh_of] if len(self.meshes) else np.zeros(0, dtype=np.int64)
        return self._tri

    @property
    def bounds(self):
        """World boxes of the objects, ``(n, 2, 3) float64`` (a new array each call; the
        last answer is kept while the matrices are the same, value for value)."""
        if not len(self):
            return np.zeros((0, 2, 3))
        memo = self._bounds_memo
        if memo is not None and np.array_equal(memo[0], self.matrices) and np.array_equal(memo[1], self.mesh_of):
            return memo[2].copy()
        # kept with copies of its inputs, computed from those copies: a matrix changed in
        # place (a move, even during this call) is a new answer
        matrices, mesh_of = self.matrices.copy(), self.mesh_of.copy()
        out = transform_boxes(self.mesh_bounds[mesh_of], matrices)
        self._bounds_memo = (matrices, mesh_of, out.copy())
        return out

    def exact_bounds(self):
        """World boxes from the transformed vertices, ``(n, 2, 3) float64``.

        Tighter than :attr:`bounds` for rotated objects; costs one pass over every
        object's vertices (done once, in bulk per object).
        """
        out = np.zeros((len(self), 2, 3))
        for i, (mesh, m) in enumerate(zip(self.mesh_of, self.matrices, strict=True)):
            v = self.meshes[mesh][0]
            if len(v):
                w = v @ m[:3, :3].T + m[:3, 3]
                out[i] = w.min(axis=0), w.max(axis=0)
        return out

    @property
    def parent(self):
        """Parent object of each object in the tree (nearest carrying ancestor), -1 if none."""
        out = np.full(len(self), -1, dtype=np.int64)
        owner = self.tree_object
        # Walk up from every tree node at once, one level per step.
        node_of_obj = np.full(len(self), -1, dtype=np.int64)
        carried = owner >= 0
        node_of_obj[owner[carried]] = np.flatnonzero(carried)
        todo = np.flatnonzero(node_of_obj >= 0)
        cur = self.tree_parent[node_of_obj[todo]]
        while len(todo):
            alive = cur >= 0
            todo, cur = todo[alive], cur[alive]
            hit = owner[cur] >= 0
            out[todo[hit]] = owner[cur[hit]]
            todo, cur = todo[~hit], self.tree_parent[cur[~hit]]
        return out
