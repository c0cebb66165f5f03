"""What an object is, by its settings alone: how it can take part in a pass (its
:class:`Kind`: a mesh, an instancer, a collection instance, or none: :func:`kind`) and
whether its evaluated state can change without an edit (:func:`is_dynamic`: such an
object is never hidden); and :class:`BulkMap`, which keeps either answer per session id
and looks it up for every object of a pass at once.  Settings only: no geometry is read."""

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

import numpy as np

from .identity import ident
from .materials import see_through

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
SOLID_DISPLAY = {"SOLID", "TEXTURED"}            # wire and bounds display never occlude


class Kind(Enum):
    """How an object can take part, by its settings alone."""

    MESH = "mesh"
    INSTANCER = "instancer"      # mesh-like, brings instances: its own geometry (where drawn) and theirs
    COLLECTION = "collection"    # an empty that instances a collection


@dataclass(frozen=True, slots=True)
class ObjectInfo:
    """What an object is, from its settings (edits report it: :meth:`.extract.Extractor.saw`
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


# Modifiers whose result depends only on the object's own data and settings
# (their animation, if any, is the object's animation_data); anything else
# (armature, hooks, booleans, geometry nodes, physics, ...) makes an object dynamic.
STATIC_MODIFIERS = {"SUBSURF", "MULTIRES", "MIRROR", "BEVEL", "SOLIDIFY", "TRIANGULATE", "WELD",
                    "DECIMATE", "EDGE_SPLIT", "WEIGHTED_NORMAL", "REMESH", "WIREFRAME", "SKIN",
                    "SMOOTH", "LAPLACIANSMOOTH", "CORRECTIVE_SMOOTH", "ARRAY", "SCREW"}


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


def is_collection_instance(obj) -> bool:
    """Whether ``obj`` instances a collection (an empty's collection instance,
    :attr:`Kind.COLLECTION`; not :attr:`Kind.INSTANCER`'s vertex, face, particle or
    geometry-nodes instances)."""
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
        if see_through(obj):
            return None                   # glass, alpha, back faces culled: what is behind shows
        parent = obj.parent
        if parent is not None and parent.instance_type in {"VERTS", "FACES"}:
            return None                   # drawn only as the parent's instances
        return Kind.INSTANCER if may_instance(obj) else Kind.MESH
    if obj.type == "EMPTY" and is_collection_instance(obj):
        if obj.display_type not in SOLID_DISPLAY or obj.show_in_front:
            return None                   # its instances are drawn as it is (wire, bounds, in front)
        if not getattr(obj, "visible_camera", True):
            return None                   # camera rays may pass through its instances too
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


# an action the add-on wrote (Apply to Render, :mod:`.render_keys`): its ``hide_render`` keys
# change nothing a pass sees, so an object carrying only those is not animated
RENDER_KEYS = "occ_render_keys"


def action_curves(action, slot=None) -> list | None:
    """The F-curves ``action`` animates through ``slot`` (slotted actions, Blender 4.4+;
    the legacy ``Action.fcurves`` before), or None where it is more than one layer's keys."""
    if hasattr(action, "layers") and (len(action.layers) or slot is not None):    # slotted (4.4+)
        if len(action.layers) > 1 or any(len(layer.strips) > 1 for layer in action.layers):
            return None
        from bpy_extras.anim_utils import action_get_channelbag_for_slot
        bag = action_get_channelbag_for_slot(action, slot)
        return [] if bag is None else list(bag.fcurves)
    return list(action.fcurves)


def render_keys_only(ad) -> bool:
    """Whether ``ad`` (animation data) animates nothing but the add-on's render keys."""
    action = ad.action
    if action is None or action.get(RENDER_KEYS) is None or len(ad.drivers) or len(ad.nla_tracks):
        return False
    curves = action_curves(action, getattr(ad, "action_slot", None))
    return curves is not None and len(curves) == 1 and curves[0].data_path == "hide_render"


def _animated(idblock):
    ad = getattr(idblock, "animation_data", None)
    return ad is not None and ((ad.action is not None and not render_keys_only(ad))
                               or len(ad.drivers) > 0 or len(ad.nla_tracks) > 0)


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


LEVELED = {"SUBSURF", "MULTIRES"}      # modifiers with a viewport and a render level
IS_VIEWPORT = "GeometryNodeIsViewport"


def _reads_is_viewport(tree, depth: int = 0) -> bool:
    """Whether a geometry-nodes tree (its groups too) asks whether it draws the viewport."""
    for node in tree.nodes:
        if node.bl_idname == IS_VIEWPORT:
            return True
        sub = getattr(node, "node_tree", None)
        if sub is not None and depth < 16 and _reads_is_viewport(sub, depth + 1):
            return True
    return False


def _levels(mod, simplify) -> tuple:
    """A leveled modifier's (viewport, render) levels, under the scene's Simplify."""
    view, render = mod.levels, mod.render_levels
    if simplify is not None:
        view, render = min(view, simplify.simplify_subdivision), min(render, simplify.simplify_subdivision_render)
    return view, render


def render_geometry(obj, scene) -> str | None:
    """Why the render may draw other geometry of ``obj`` than the viewport does (what a
    pass reads), in words, or None: the same settings draw both.  Settings only: a
    modifier on in one and off in the other, subdivision levels, a geometry-nodes tree
    that asks whether it draws the viewport, particle amounts and display, curve and
    metaball resolutions."""
    simplify = scene.render if scene.render.use_simplify else None
    for mod in obj.modifiers:
        if mod.show_viewport != mod.show_render:
            return f"its modifier '{mod.name}' is on in only one of the viewport and the render"
        if not mod.show_viewport:
            continue
        if mod.type in LEVELED:
            view, render = _levels(mod, simplify)
            if view != render:
                return f"its modifier '{mod.name}' subdivides {render} levels in the render, {view} in the viewport"
        if mod.type == "NODES" and mod.node_group is not None and _reads_is_viewport(mod.node_group):
            return f"its modifier '{mod.name}' asks whether it draws the viewport"
    for ps in getattr(obj, "particle_systems", ()):
        s = ps.settings
        if s.display_percentage != 100 or s.display_method != "RENDER":
            return f"its particles '{ps.name}' are displayed other than rendered (amount or display)"
        if s.child_type != "NONE" and s.child_percent != s.rendered_child_count:
            return (f"its particles '{ps.name}' have {s.rendered_child_count} children in the render, "
                    f"{s.child_percent} in the viewport")
        if simplify is not None and s.child_type != "NONE" \
                and simplify.simplify_child_particles != simplify.simplify_child_particles_render:
            return "the scene's Simplify thins child particles differently in the viewport and the render"
    data = obj.data
    if obj.type in {"CURVE", "SURFACE", "FONT"}:
        for axis in ("u", "v"):
            render = getattr(data, f"render_resolution_{axis}", 0)
            if render and render != getattr(data, f"resolution_{axis}", render):
                return f"its curve resolution ({axis}) is {render} in the render"
    if obj.type == "META" and data.render_resolution != data.resolution:
        return "its metaball resolution differs in the render"
    return None
