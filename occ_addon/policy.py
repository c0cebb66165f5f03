"""The never-hide policy: what a pass may hide, and what an analysis counts as seen
beyond the engine's answer.  Cull (:meth:`.session.Session.cull`) and analyze
(:mod:`.analysis`) read it from here, so both keep the same rules.

Never hidden, whatever the engine answers:

- the user's "never cull" flag and the exclusion collection (``scene.occ``);
- members of instanced collections (hiding a member would hide its instances
  too), of the instances the engine holds and of those it does not hold (drawn
  as wire or bounds, in front: :func:`.drawn.bystanders`);
- an instance of a collection with a member that draws without occluding (wire,
  bounds, "in front", point clouds, ...: :func:`draws_beyond_geometry`): the
  instance is larger than the engine's box of it;
- dynamic objects (:func:`.kinds.is_dynamic`: Blender stops evaluating what is
  hidden);
- the selection and the active object (:func:`chosen`): Blender draws a selected
  object's outline and origin over what stands before it, and the user's tools act on
  it only while it is drawn; an object that shows its name (drawn over walls too);
- what the view shows beyond depth (:func:`drawn_beyond_depth`, :mod:`.shading`).

Analyze counts the same instances as seen wherever they are drawn, and the members
of every visible instance as seen (:func:`members_seen`).
"""

from typing import NamedTuple

import numpy as np

from ..core import Visibility
from . import identity, visibility
from .drawn import DRAWN_TYPES, bystanders
from .identity import ident
from .kinds import is_collection_instance, kind


def draws_beyond_geometry(instanced) -> bool:
    """Whether any of ``instanced`` (what an instancer instances: a collection's objects,
    a particle system's object) is drawn by Blender but left out of the engine's geometry
    of the instances (wire, bounds or "in front" display, point clouds, volumes, ...):
    such an instance may stand anywhere, so the instancer is larger than its box in the
    engine."""
    return any(kind(m) is None and m.type in DRAWN_TYPES for m in instanced)


def drawn_beyond_depth(view_rule, state: np.ndarray, cull_raytraced: bool) -> np.ndarray:
    """``(k,) bool``: what the view shows of the engine's objects beyond their depth
    (:mod:`.shading`): everything in a view that hides nothing (a Quad View) and under
    ray tracing (unless the user opted in with ``cull_raytraced``), every occluded object
    under X-ray, and what lies outside the pass's view where the view draws beyond it (a
    camera's passepartout).  (Shadow casters under scene lights are the engine's: the pass
    was given the lights.)"""
    n = len(state)
    if view_rule.mode == "shown" or (view_rule.mode == "raytraced" and not cull_raytraced):
        return np.ones(n, dtype=bool)
    keep = state == Visibility.VIEW_CULLED if view_rule.outside_shows else np.zeros(n, dtype=bool)
    if view_rule.mode == "xray":
        keep |= state == Visibility.OCCLUDED
    return keep


class Settled(NamedTuple):
    """What :func:`never_hidden` knows before the engine answers: ``flagged``, ``(k,)
    bool`` never hidden whatever it answers, and ``instances``, ``[(collection, [k, ...])]``
    the collection instances among the engine's objects by collection (never hidden
    where one is culled and the collection draws beyond its geometry)."""

    flagged: np.ndarray
    instances: list


def chosen(view_layer, picked=None) -> np.ndarray:
    """Session ids of the objects selected in ``view_layer`` and of its active object
    (``picked``: an object the add-on selected for a moment, not the user's).  Blender
    draws their outline and origin over what stands before them (measured in a window,
    Blender 3.4: a selected box behind a wall showed its outline through the wall, and
    a pass took it away), and hiding one takes it out of what the user's tools act on."""
    objects = view_layer.objects
    found = [identity.idents(objects.selected)]
    if objects.active is not None:
        found.append(identity.idents([objects.active]))
    out = np.concatenate(found)
    try:
        return out if picked is None else out[out != identity.ident(picked)]
    except ReferenceError:                    # removed since: not among them
        return out


def hides_chosen(view_layer) -> bool:
    """Whether an object the add-on hides is selected or active in ``view_layer``
    (selected in the outliner or by a script while hidden: :func:`chosen`): asked at every
    change of the scene alone, so one by one over a small selection (a bulk read of every
    object's records costs 10-30 ms at 50,000 objects)."""
    objects = view_layer.objects
    picked = list(objects.selected)
    if objects.active is not None:
        picked.append(objects.active)
    if len(picked) > 2000:
        culled = visibility.culled()
        return bool(culled.any() and np.isin(identity.idents(picked), identity.uids()[culled]).any())
    return any(o.occ_culled or getattr(o, identity.VIEW_RECORD) for o in picked)


def settled(context, objects: list, uids: np.ndarray, collection: np.ndarray, picked=None) -> Settled:
    """The part of :func:`never_hidden` that does not depend on the engine's answer
    (the same arguments; ``picked``: see :func:`chosen`): read while the engine culls."""
    settings = context.scene.occ
    flagged = [identity.uids()[identity.flags("occ_never_cull")], chosen(context.view_layer, picked)]
    coll = settings.exclude_collection
    if coll is not None:
        flagged.append(identity.uids(coll.all_objects if settings.exclude_children else coll.objects))
    colls = {}                                         # collection id -> (collection, its instances' k)
    for k in np.flatnonzero(collection):
        c = objects[k].instance_collection
        colls.setdefault(ident(c), (c, []))[1].append(k)
    for c, _ in colls.values():
        flagged.append(identity.uids(c.all_objects))
    # ... and so are those of instances the engine does not hold (drawn as wire or
    # bounds, in front): hiding a member would take it out of them too
    for o in bystanders(context.view_layer, uids):
        if is_collection_instance(o) and ident(o.instance_collection) not in colls:
            flagged.append(identity.uids(o.instance_collection.all_objects))
    # ... and what a particle system instances (its object, its collection's members):
    # hiding one takes it out of the particles' instances, which may be seen
    flagged.append(identity.idents(visibility.particle_instanced()))
    return Settled(np.isin(uids, np.concatenate(flagged)), list(colls.values()))


def never_hidden(context, objects: list, uids: np.ndarray, collection: np.ndarray, culled: np.ndarray,
                 extractor, known: Settled | None = None) -> np.ndarray:
    """``(k,) bool`` over the engine's objects (``objects``, their session ids ``uids``
    and ``collection``: which are collection instances): never hidden (see the module
    docstring).  ``culled``: where the engine would hide; the per-object questions
    (dynamic, an instance's members) are asked only there.  ``known``: :func:`settled`
    of the same objects, read in the same pass (default: read here)."""
    if known is None:
        known = settled(context, objects, uids, collection)
    out = known.flagged.copy()
    for c, at in known.instances:
        if culled[at].any() and draws_beyond_geometry(c.all_objects):
            out[at] = True
    at = np.flatnonzero(culled & ~out)
    # an object that shows its name: Blender draws the name over walls (measured, 3.4: 85 px);
    # read where the engine would hide only (a bulk read of every object costs more)
    named = np.fromiter((objects[k].show_name for k in at.tolist()), dtype=bool, count=len(at))
    out[at[named]] = True
    at = at[~named]                                    # cached, in bulk: what Blender has no bulk form of
    out[at] = extractor.dynamic_of(objects, uids, at)
    return out


def instancers(objects: list) -> list[int]:
    """Indices of the collection instances among ``objects``."""
    return [i for i, o in enumerate(objects) if is_collection_instance(o)]


def widen_instances(objects: list, instancing: list[int], vis: np.ndarray) -> None:
    """Count as seen (in ``vis``, ``(k,) bool``, in place) every instancer in
    ``instancing`` (collection instances, emitters) that instances something drawn
    beside its geometry (wire, bounds, ...): the engine knows only its solid part,
    and it is seen wherever it is drawn (conservative by construction; workflow seed
    7155 on Blender 4.2: a hair emitter whose instance object is drawn as wire, its own
    mesh out of view, its wire instances in it)."""
    wide = {}                                          # collection name -> the answer, once a call
    for i in (i for i in instancing if not vis[i]):
        o = objects[i]
        c = o.instance_collection if o.instance_type == "COLLECTION" else None
        if c is not None and c.name_full not in wide:
            wide[c.name_full] = draws_beyond_geometry(c.all_objects)
        vis[i] = (c is not None and wide[c.name_full]) or draws_beyond_geometry(_particle_instanced(o))


def emitters(objects: list) -> list[int]:
    """Indices of the objects among ``objects`` whose particle systems instance objects."""
    return [i for i, o in enumerate(objects)
            if any(ps.settings.render_type in {"OBJECT", "COLLECTION"} for ps in o.particle_systems)]


def instanced_members(o) -> list:
    """The objects ``o`` draws through instancing: its instance collection's objects,
    and what its particle systems instance (an object, or a collection's objects)."""
    out = list(o.instance_collection.all_objects) \
        if o.instance_type == "COLLECTION" and o.instance_collection is not None else []
    return out + _particle_instanced(o)


def _particle_instanced(o) -> list:
    """What the particle systems of ``o`` instance: an object, or a collection's objects."""
    out = []
    for ps in o.particle_systems:
        st = ps.settings
        if st.render_type == "OBJECT" and st.instance_object is not None:
            out.append(st.instance_object)
        elif st.render_type == "COLLECTION" and st.instance_collection is not None:
            out.extend(st.instance_collection.all_objects)
    return out


def members_seen(objects: list, instances: list[int], vis: np.ndarray, emitting: list[int] = (),
                 bystanders: list = ()) -> list:
    """Objects seen beside the engine's visible ones through instances: the members of
    every visible collection instance (an object is seen where an instance draws it),
    and what the particles of every visible emitter in ``emitting`` instance (the
    engine holds those instances as the emitter's geometry); the same of every one of
    ``bystanders``: what Blender draws that the engine does not hold
    (:func:`.drawn.bystanders`: never culled, so visible; workflow seed 7032: a hair
    emitter left out of the engine, its hair collection's member left out of the report)."""
    drawing = [objects[i] for i in sorted(set(instances) | set(emitting)) if vis[i]] + list(bystanders)
    return [m for o in drawing for m in instanced_members(o)]
