"""Analyze a camera path: cull from the scene camera frame by frame, hiding nothing,
and write what it sees (JSON and CSV); optionally collect the never-visible objects.

What counts as seen beyond the engine's answer is :mod:`.policy`'s (the same rules
a pass keeps to).  Every frame is culled as a new engine's first pass, so a frame's
answer never depends on the frames before it: reports of frame ranges (chunks, on a
farm) merge into exactly the report of one run over all of them (``python -m core
merge``; the report is :mod:`..core.analysis`'s, the same the command line writes).
The work runs as a generator (:func:`analysis_steps`, see :func:`.worker.drive`): a
window drives it from a modal operator's timer, a script at once.
"""

import os
import time
from collections.abc import Generator
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..core import Visibility, repeatable
from ..core import analysis as report
from . import keyed_camera, policy
from .cameras import scene_camera
from .drawn import left_out_of_render
from .kinds import render_geometry
from .session import SESSION
from .shading import rule as rule_of
from .worker import Progress, quiet


@dataclass
class Analysis:
    """What an analysis found: ``frames`` analyzed, the report ``path``, per frame
    ``{"frame": f, "visible": [names]}``, per object name the number of frames it is
    seen in (0: never), when it started (``time.perf_counter()``), its ``rule``
    ("seen" or "render") and its ``source``: what two chunks of one analysis share
    (:func:`source`)."""

    frames: list[int]
    path: str
    per_frame: list[dict]
    seen: dict[str, int]
    started: float
    rule: str
    source: dict = field(default_factory=dict)

    @property
    def never_visible(self) -> list[str]:
        return sorted(n for n, c in self.seen.items() if c == 0)


def source(context, rule: str, step: int) -> dict:
    """The identity of an analysis (:func:`..core.analysis.source_block`): the blend
    file's name and the scene's, its objects' names, and the settings that change an
    answer.  Chunks whose sources differ are not merged."""
    scene = context.scene
    s, r = scene.occ, scene.render
    settings = {"strategy": repeatable(s.strategy), "preset": s.preset, "max_resolution": s.max_resolution,
                "rule": rule,
                "frame_step": int(step), "cull_raytraced": bool(s.cull_raytraced),
                "render_resolution": [r.resolution_x, r.resolution_y, r.resolution_percentage],
                "view_layer": context.view_layer.name,
                "exclude_collection": s.exclude_collection.name if s.exclude_collection else None,
                "exclude_children": bool(s.exclude_children)}
    return report.source_block(scene.name, sorted(o.name for o in scene.objects), settings,
                               file=bpy.path.basename(bpy.data.filepath))


# the camera from its keys where a frame change moves nothing else (see .keyed_camera);
# False: every frame evaluated in full (tests compare the two)
KEYED = True


def evaluate(context, frame: int) -> list:
    """Evaluate ``frame`` in full (``scene.frame_set``) for the context's view layer, and
    return what that frame change evaluated (:func:`.keyed_camera.evaluate_frame`)."""
    moving = keyed_camera.evaluate_frame(context.scene, frame)
    # this layer's evaluation, written back to the originals the candidates read in
    # bulk; with several view layers or scenes every frame re-evaluates every
    # transform first (another layer's evaluation can leave one behind)
    SESSION.reread_transforms()
    context.view_layer.update()
    return moving


def keyed_frames(context, frames: list[int], moving: list, lights_count: bool):
    """The scene camera from its keys over ``frames`` (:class:`.keyed_camera.KeyedCamera`),
    or None: every frame is evaluated in full.  ``moving``: what the first frame's change
    evaluated (the scene is at ``frames[0]``).  The keys must give Blender's own camera at
    the range's first and last frames, and nothing else may move at either; the scene is
    left evaluated at one of them (with the keys, every frame's scene)."""
    scene = context.scene
    keys = keyed_camera.probe(scene, moving, lights_count)
    if keys is None or len(frames) == 1:
        return keys
    if keyed_camera.probe(scene, evaluate(context, frames[-1]), lights_count) is None:
        evaluate(context, frames[0])          # back where the range starts, frame by frame
        return None
    return keys


def analysis_steps(context, frames: list[int], path: str, rule: str = "seen",
                   step: int = 1) -> Generator[object, None, Analysis]:
    """Analyze in steps (a generator, see :func:`.worker.drive`): one a frame, and a
    first build's own.  Stopped early (Esc), the scene goes back to its frame and
    nothing is written.  ``rule``: "seen" (a pixel of it seen) or "render" (seen, or
    shown beyond its pixels under the render engine: shadows, rays; :mod:`.shading`);
    ``step``: the frame step of ``frames`` (part of the report's identity)."""
    scene = context.scene
    previous = scene.frame_current
    out = Analysis(frames, path, [], {}, time.perf_counter(), rule, source(context, rule, step))
    seen = out.seen
    held = held_names = instances = emitting = extra = keys = redrawn = None
    every = max(1, len(frames) // 10)         # background mode: about ten progress lines
    try:
        for k, f in enumerate(frames):
            if keys is None:
                moving = evaluate(context, f)
                if k == 0:
                    if KEYED and bpy.app.background:   # in a window the user may edit between frames
                        keys = keyed_frames(context, frames, moving, rule == "render")
                    # how the camera was found is part of the answer: chunks found otherwise
                    # (their cameras may differ in the last bit) are not merged
                    out.source["settings"]["camera"] = "keys" if keys is not None else "frames"
            # the camera from its keys where only the camera moves (every frame of the range:
            # a chunk's answers are the whole run's), else the frame Blender just evaluated
            camera, display = scene_camera(context, matrix=None if keys is None else keys.matrix_world(f))
            # nothing is hidden; every frame a new engine's first pass (restart): its answer
            # never depends on the frames before it, so chunks of the range merge exactly
            view_rule = rule_of(context, "CAMERA") if rule == "render" else None
            # a fresh pass each frame, by a strategy whose answer does not depend on timing:
            # the same file and settings give the same report, and chunks merge exactly;
            # with the keys in background mode nothing in the scene changes between frames
            # (no frame change, no user): the candidates read once stand
            still = keys is not None and k > 0
            result, objects = yield from SESSION.compute_steps(context, camera, display, restart=True,
                                                               lights=view_rule.lights if view_rule else None,
                                                               strategy=repeatable(scene.occ.strategy),
                                                               reuse=still)
            if SESSION.held is not held:        # the engine's objects changed: their names, once
                held = SESSION.held
                held_names = [o.name for o in objects]
                instances = policy.instancers(objects)
                emitting = policy.emitters(objects)
                # the render may draw these otherwise than the viewport the pass reads
                redrawn = np.array([render_geometry(o, scene) is not None for o in objects], dtype=bool) \
                    if rule == "render" else None
                for n in held_names:
                    seen.setdefault(n, 0)
            if not still or extra is None:      # what Blender draws beside the engine's objects
                extra = policy.bystanders(context.view_layer, held.uids)
            vis = result.state == Visibility.VISIBLE          # one array compare, no per-object enum
            if view_rule is not None:          # shadow casters are the engine's (given the lights)
                vis |= policy.drawn_beyond_depth(view_rule, result.state, scene.occ.cull_raytraced)
                # an occluder in view that the render leaves out (its own or its
                # collection's render hide) or draws otherwise (kinds.render_geometry) may
                # show the render what it covers: every occluded object counts as seen (one
                # hidden or outside occludes nothing alone); one drawn otherwise is seen
                off = left_out_of_render(context.view_layer, held.uids) | redrawn
                if ((result.state == Visibility.VISIBLE) & off).any():
                    vis |= result.state == Visibility.OCCLUDED
                vis |= redrawn
            policy.widen_instances(objects, instances + emitting, vis)
            if SESSION.extractor.beyond:        # instances drawn as wire, bounds, ...: seen where drawn
                vis |= np.isin(held.uids, np.fromiter(SESSION.extractor.beyond, dtype=np.int64))
            shown = [held_names[i] for i in np.flatnonzero(vis)]
            others = [o.name for o in extra + policy.members_seen(objects, instances, vis, emitting, extra)]
            names = list(dict.fromkeys(shown + others))
            out.per_frame.append({"frame": f, "visible": names})
            for n in others:
                seen.setdefault(n, 0)
            for n in names:
                seen[n] += 1
            if bpy.app.background and ((k + 1) % every == 0 or k + 1 == len(frames)):
                print(f"occlusion analyze: {k + 1}/{len(frames)} frames "
                      f"({time.perf_counter() - out.started:.1f} s)", flush=True)
            yield Progress(f"frame {k + 1}/{len(frames)}", (k + 1) / len(frames))
    finally:
        scene.frame_set(previous)
    return out


def report_path(filepath: str) -> str:
    """Absolute report path.  ``//`` is the blend file's folder; in a file never saved
    it is the working directory (sub-folders kept), never Blender's temporary folder,
    which is deleted at exit."""
    if filepath.startswith("//") and not bpy.data.filepath:
        return os.path.normpath(os.path.join(os.getcwd(), filepath[2:]))
    return os.path.normpath(bpy.path.abspath(filepath))


def write_report(analysis: Analysis) -> None:
    """JSON: per frame the visible objects, per object the frames it is visible in, the
    rule that says what "visible" means ("seen" or "render"), the frames analyzed and
    the analysis's identity; CSV beside it (:mod:`..core.analysis`: the report the
    command line writes and merges)."""
    report.write_report(report.build_report(analysis.per_frame, analysis.seen, analysis.rule, analysis.source),
                        analysis.path)


def push_undo(message: str) -> None:
    """Make what an operator just changed an undo step of its own, as every edit is.

    Needed after any change that creates a datablock and links it to existing ones
    (the "Never Visible" collection in the scene's children): Blender's memfile undo
    keeps in place every datablock whose saved state did not change between the two
    undo steps it moves across, and knows nothing of changes made after the last
    push.  Undo without this step restores the scene as it is now, still pointing at
    the new collection, which the undo frees: a view layer then holds a freed
    collection (a crash, or Python reading it as a bare ``ID``).  With the step, the
    scene differs between the steps and is read back, the collection with it.

    The operators carry no UNDO flag (Cull and Restore must not add steps, and a
    script's ``bpy.ops`` call pushes nothing for it anyway), so the push is explicit.
    Headless without an undo history (the common script) nothing is pushed: nothing
    can be undone there, and a first push would copy the whole file into memory."""
    if not bpy.app.background or bpy.ops.ed.undo_history.poll():
        quiet()                                      # no engine thread runs while an operator does
        bpy.ops.ed.undo_push(message=message)


def link_collection(scene, name: str, object_names: list[str]) -> tuple[int, list[str]]:
    """Make the add-on's part of collection ``name`` exactly ``object_names``; returns
    ``(how many it links now, the names in it it leaves although this analysis saw them)``.

    The add-on owns only what it linked there (the ``occ_collected`` record on the
    object): an object the user put there is the user's, and stays whatever the
    analysis says.  One the add-on linked is unlinked again once an analysis sees it
    (deleting the collection's contents must never delete what the camera sees),
    unless it is the object's last collection: an object in no collection is not
    written at the next save, so that one stays, and becomes the user's.  The
    collection is excluded in every view layer of every scene that links it: it gives
    its objects no way into a view layer, so linking changes nothing anyone sees (an
    object whose own collection is excluded stays out)."""
    coll = bpy.data.collections.get(name) or bpy.data.collections.new(name)
    if coll.name not in scene.collection.children:
        # excluded before its objects are linked: they never get a base through it
        scene.collection.children.link(coll)
    exclude_everywhere(coll)
    wanted = set(object_names)
    kept = []
    for obj in [o for o in coll.objects if o.name not in wanted]:
        if obj.occ_collected and len(obj.users_collection) > 1:
            coll.objects.unlink(obj)
            obj.occ_collected = False
        else:
            if obj.occ_collected:               # its only home now (the user moved it there)
                obj.occ_collected = False
            kept.append(obj.name)
    linked = 0
    for n in object_names:
        obj = bpy.data.objects.get(n)
        if obj is not None and obj.name not in coll.objects:
            coll.objects.link(obj)
            obj.occ_collected = True
            linked += 1
    return linked, kept


def exclude_everywhere(coll) -> None:
    """Exclude ``coll`` in every view layer where it appears (any depth)."""
    for scene in bpy.data.scenes:
        for layer in scene.view_layers:
            stack = [layer.layer_collection]
            while stack:
                lc = stack.pop()
                if lc.collection == coll:
                    if not lc.exclude:
                        lc.exclude = True
                    continue
                stack.extend(lc.children)
