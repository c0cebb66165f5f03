"""Scenes as plain arrays: objects, their (possibly shared) meshes, world matrices
and the scene tree.

An *object* is a scene-graph node that carries triangles; its name is the node
name.  Meshes are stored once and referenced by ``mesh_of``, so a mesh placed a
thousand times is uploaded once.  The tree (``tree_parent``, ``tree_object``)
is the scene's own grouping -- glTF nodes, Blender collections -- and is the
skeleton the hierarchy builder starts from.
"""

import io
import json
import os
import re
import struct
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
        """World boxes of the objects, ``(n, 2, 3) float64``."""
        if not len(self):
            return np.zeros((0, 2, 3))
        return transform_boxes(self.mesh_bounds[self.mesh_of], self.matrices)

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


# Loaders trimesh imports only when a file needs them: suffix -> (modules, pip packages).
OPTIONAL_DECODERS = {
    ".dae": (("collada",), "pycollada"),
    ".3mf": (("lxml", "networkx"), "lxml networkx"),
    ".3dxml": (("lxml", "PIL"), "lxml pillow"),
    ".step": (("cascadio",), "cascadio"),
    ".stp": (("cascadio",), "cascadio"),
}
# glTF extensions that change how geometry is stored -> (module, pip package) or None (no decoder).
GLTF_DECODERS = {
    "KHR_draco_mesh_compression": ("DracoPy", "DracoPy"),
    "EXT_meshopt_compression": None,
    "KHR_meshopt_compression": None,
}
MESH_TAG = "_occ_mesh_index"        # written into each glTF mesh's extras while loading
GLB_MAGIC, GLB_JSON, GLB_BIN = b"glTF", 0x4E4F534A, 0x004E4942


def _missing(modules):
    import importlib.util
    return [m for m in modules if importlib.util.find_spec(m) is None]


def load_scene(path):
    """Load anything trimesh reads as a Scene (glTF/GLB, OBJ, PLY, ...).

    glTF/GLB nodes are read here, not by trimesh, so that names and order are
    stable: objects in file (node index) order, named by their node; repeated
    names get Blender's ``.001``, ``.002`` suffixes in file order, and a node
    without a name is named by its mesh (or ``object``).  A mesh of several
    primitives is one object, as in Blender's importer.
    """
    try:
        import trimesh
    except ImportError:
        raise OccError("reading scene files needs trimesh: pip install trimesh") from None
    path = os.fspath(path)
    if os.path.isdir(path):
        raise OccError(f"{path} is a directory, not a scene file")
    if not os.path.isfile(path):
        raise OccError(f"scene file not found: {path}")
    suffix = os.path.splitext(path)[1].lower()
    modules, packages = OPTIONAL_DECODERS.get(suffix, ((), ""))
    if _missing(modules):
        raise OccError(f"reading {suffix} files needs {packages}: pip install {packages}")
    try:
        if suffix in (".glb", ".gltf"):
            return _load_gltf(path, suffix, trimesh)
        loaded = trimesh.load(path, force="scene")
    except OccError:
        raise
    except Exception as e:  # trimesh raises many types for malformed files
        raise OccError(f"cannot read scene file {path}: {type(e).__name__}: {e}") from None
    return scene_from_trimesh(loaded)


def blender_names(bases):
    """Unique names in order, Blender's way: a taken name gets the first free ``.001``,
    ``.002``, ... of its stem (a numeric suffix of its own is not part of the stem)."""
    taken, out, last = set(), [], {}
    for base in bases:
        name = base
        if name in taken:
            stem = re.sub(r"\.\d{3,}$", "", base)
            k = last.get(stem, 0)
            while name in taken:
                k += 1
                name = f"{stem}.{k:03d}"
            last[stem] = k
        taken.add(name)
        out.append(name)
    return out


def _read_gltf_header(path, suffix):
    """(header dict, GLB binary chunk or None) of a .gltf or .glb file."""
    with open(path, "rb") as f:
        data = f.read()
    if suffix == ".gltf":
        return json.loads(data.decode("utf-8")), None
    if len(data) < 20 or data[:4] != GLB_MAGIC:
        raise OccError(f"cannot read scene file {path}: not a GLB file (no glTF header)")
    length, kind = struct.unpack_from("<II", data, 12)
    if kind != GLB_JSON:
        raise OccError(f"cannot read scene file {path}: its first GLB chunk is not JSON")
    header = json.loads(data[20:20 + length].decode("utf-8"))
    rest = 20 + length
    binary = None
    if rest + 8 <= len(data):
        blen, bkind = struct.unpack_from("<II", data, rest)
        if bkind == GLB_BIN:
            binary = data[rest + 8:rest + 8 + blen]
    return header, binary


def _check_gltf_extensions(header, path):
    used = set(header.get("extensionsUsed", ())) | set(header.get("extensionsRequired", ()))
    for ext in sorted(used & set(GLTF_DECODERS)):
        decoder = GLTF_DECODERS[ext]
        if decoder is None:
            raise OccError(f"{path} uses {ext}, which the loader cannot decode; re-export it "
                           "without that compression")
        module, package = decoder
        if _missing((module,)):
            raise OccError(f"{path} is compressed with {ext}; reading it needs {package}: "
                           f"pip install {package}")


def _glb_bytes(header, binary):
    """A GLB file of ``header`` and ``binary``, chunks padded to 4 bytes as the format asks."""
    js = json.dumps(header).encode("utf-8")
    js += b" " * (-len(js) % 4)
    chunks = struct.pack("<II", len(js), GLB_JSON) + js
    if binary is not None:
        binary = binary + b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(binary), GLB_BIN) + binary
    return GLB_MAGIC + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def _node_matrix(node):
    """A glTF node's local matrix, ``(4, 4) float64``: its matrix, or T @ R @ S."""
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
    m = np.eye(4)
    q = np.asarray(node.get("rotation", (0.0, 0.0, 0.0, 1.0)), dtype=np.float64)
    x, y, z, w = q / (np.linalg.norm(q) or 1.0)      # exporters round unit quaternions
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, :3] *= np.asarray(node.get("scale", (1.0, 1.0, 1.0)), dtype=np.float64)
    m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return m


def _load_gltf(path, suffix, trimesh):
    header, binary = _read_gltf_header(path, suffix)
    _check_gltf_extensions(header, path)
    nodes, gmeshes = header.get("nodes", []), header.get("meshes", [])
    # trimesh decodes the meshes; a tag in each mesh's extras says which glTF mesh a
    # decoded primitive came from (trimesh names primitives its own way)
    for i, m in enumerate(gmeshes):
        extras = m.get("extras")
        m["extras"] = {**(extras if isinstance(extras, dict) else {}), MESH_TAG: i}
    if suffix == ".glb":
        tm = trimesh.load(io.BytesIO(_glb_bytes(header, binary)), file_type="glb", force="scene")
    else:
        tm = trimesh.load(io.BytesIO(json.dumps(header).encode("utf-8")), file_type="gltf",
                          resolver=trimesh.resolvers.FilePathResolver(path), force="scene")
    parts = {}
    for geom in tm.geometry.values():           # primitives in file order
        tag = geom.metadata.get(MESH_TAG) if isinstance(geom.metadata, dict) else None
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces) and tag is not None:
            parts.setdefault(int(tag), []).append(geom)

    # the node tree from the default scene's roots, parents before children
    if header.get("scenes"):
        roots = header["scenes"][header.get("scene", 0)].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", ())}
        roots = [i for i in range(len(nodes)) if i not in children]
    parent, world, order = {}, {}, []
    stack = [(r, -1) for r in reversed(roots)]
    while stack:
        i, p = stack.pop()
        if i in parent or not 0 <= i < len(nodes):
            continue                             # a node has one parent; no cycles
        parent[i] = p
        world[i] = (world[p] if p >= 0 else np.eye(4)) @ _node_matrix(nodes[i])
        order.append(i)
        stack.extend((c, i) for c in reversed(nodes[i].get("children", ())))
    reached = sorted(order)                      # file order
    bases = []
    for i in reached:
        n = nodes[i]
        mesh_name = gmeshes[n["mesh"]].get("name") if "mesh" in n and n["mesh"] < len(gmeshes) else None
        bases.append(str(n.get("name") or mesh_name or "object"))
    unique = dict(zip(reached, blender_names(bases), strict=True))

    mesh_index, meshes = {}, []
    names, mesh_of, matrices = [], [], []
    tree_index = {i: k for k, i in enumerate(reached)}
    tree_object = np.full(len(reached), -1, dtype=np.int64)
    for i in reached:
        m = nodes[i].get("mesh")
        if m not in parts:
            continue
        if m not in mesh_index:                  # one mesh per glTF mesh, shared by its nodes
            geoms = parts[m]
            offsets = np.cumsum([0] + [len(g.vertices) for g in geoms[:-1]])
            mesh_index[m] = len(meshes)
            meshes.append((np.concatenate([np.asarray(g.vertices, dtype=np.float64) for g in geoms]),
                           np.concatenate([np.asarray(g.faces, dtype=np.int64) + o
                                           for g, o in zip(geoms, offsets, strict=True)])))
        tree_object[tree_index[i]] = len(names)
        names.append(unique[i])
        mesh_of.append(mesh_index[m])
        matrices.append(world[i])
    tree_parent = np.array([tree_index.get(parent[i], -1) for i in reached], dtype=np.int64)
    return Scene(names, meshes, np.array(mesh_of, dtype=np.int64),
                 np.array(matrices, dtype=np.float64).reshape(-1, 4, 4), tree_parent, tree_object)


def scene_from_trimesh(tm_scene):
    """Convert a ``trimesh.Scene`` into a :class:`Scene` (shared geometry stays shared)."""
    import trimesh

    graph = tm_scene.graph
    base = graph.base_frame
    geometry_nodes = set(graph.nodes_geometry)
    parents = graph.transforms.parents
    nodes = [n for n in graph.nodes if n != base]
    index = {n: i for i, n in enumerate(nodes)}
    mesh_index, meshes = {}, []
    names, mesh_of, matrices = [], [], []
    tree_object = np.full(len(nodes), -1, dtype=np.int64)
    for i, node in enumerate(nodes):
        if node not in geometry_nodes:
            continue
        matrix, geom_name = graph[node]
        geom = tm_scene.geometry.get(geom_name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        if geom_name not in mesh_index:
            mesh_index[geom_name] = len(meshes)
            meshes.append((np.asarray(geom.vertices, dtype=np.float64),
                           np.asarray(geom.faces, dtype=np.int64)))
        tree_object[i] = len(names)
        names.append(str(node))
        mesh_of.append(mesh_index[geom_name])
        matrices.append(np.asarray(matrix, dtype=np.float64))
    tree_parent = np.array([index.get(parents.get(n), -1) for n in nodes], dtype=np.int64)
    return Scene(names, meshes, np.array(mesh_of, dtype=np.int64),
                 np.array(matrices).reshape(-1, 4, 4), tree_parent, tree_object)
