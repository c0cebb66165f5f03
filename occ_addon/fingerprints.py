"""What an object's cached geometry was read from, as a comparable value (its
*fingerprint*): taken before the add-on hides the object everywhere, from then on not
evaluated and its edits not reported (:meth:`.extract.Extractor.seal`), and compared
when a pass verifies it (:meth:`.extract.Extractor.unchanged`)."""

import zlib

import bpy
import numpy as np

from .identity import ident
from .kinds import Kind
from .meshes import corner_vertices, positions


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
                           zlib.crc32(corner_vertices(mesh)), _shape_keys_fingerprint(mesh))
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
