"""Scene files into :class:`core.scene.Scene`: glTF/GLB read node by node (stable
names and order), anything else through trimesh; a clear error for what cannot be read.
"""

import io
import json
import os
import re
import struct

import numpy as np

from .errors import OccError
from .scene import Scene

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
