"""Analyze (occ_addon/analysis.py): the report's path and progress, the never-visible
collection."""

import io
import json
import os
import subprocess
import sys
from contextlib import redirect_stdout

import bpy

from .common import ROOT, WORK, box, check, drawn, keyframes, new_scene, update


def report_path_and_progress():
    """analyze in a file never saved: '//' is the working directory (sub-folders kept),
    never Blender's temporary folder; background mode prints progress lines."""
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    out = io.StringIO()
    with redirect_stdout(out):
        r = bpy.ops.occ.analyze(filepath="//occ_reports/unsaved.json", frame_start=1, frame_end=20)
    path = os.path.join(os.getcwd(), "occ_reports", "unsaved.json")
    check("analyze_unsaved_path_in_cwd", r == {"FINISHED"} and os.path.exists(path), (r, path))
    lines = [ln for ln in out.getvalue().splitlines() if ln.startswith("occlusion analyze:")]
    check("analyze_background_progress", 2 <= len(lines) <= 12 and "20/20" in lines[-1], lines)
    chunks_merge_to_whole()


def chunks_merge_to_whole():
    """occ.analyze over frames 1-3 and 4-6 (a farm's chunks), joined by ``python -m core
    merge``, is byte for byte occ.analyze over 1-6: every frame is a new engine's first
    pass.  The camera walks along the wall, so the frames see different boxes."""
    new_scene()
    for i, y in enumerate((-8, -4, 4, 8)):
        box(f"behind_{i}", (3, y - 0.5, 0), (4, y + 0.5, 1))
    keyframes(bpy.data.objects["cam"], [(1, (-10.0, -9.0, 1.0)), (6, (-10.0, 9.0, 1.0))])
    update()
    whole = os.path.join(WORK, "chunks_whole", "report.json")
    bpy.ops.occ.analyze(filepath=whole, frame_start=1, frame_end=6)
    for a, b in ((4, 6), (1, 3)):
        bpy.ops.occ.analyze(filepath=os.path.join(WORK, "chunks", f"chunk_{a}_{b}.json"), frame_start=a, frame_end=b)
    merged = os.path.join(WORK, "chunks_merged")
    p = subprocess.run([sys.executable, "-m", "core", "merge", os.path.join(WORK, "chunks"), "--out", merged],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    same = p.returncode == 0 and all(
        open(os.path.join(merged, f"report.{ext}"), "rb").read() == open(whole[:-4] + ext, "rb").read()
        for ext in ("json", "csv"))
    with open(whole) as f:
        seen = {tuple(fr["visible"]) for fr in json.load(f)["frames"]}
    check("analyze_chunks_merge_to_whole", same and len(seen) > 1, (p.returncode, p.stderr[-500:], seen))


def never_visible_exact():
    """"Collect Never Visible" holds exactly what the last analysis never saw."""
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    report = os.path.join(WORK, "never_visible_exact.json")
    bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1, link_never_visible=True)
    first = {o.name for o in bpy.data.collections["Never Visible"].objects}
    bpy.data.objects["wall"].location.z = -20.0
    update()
    bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1, link_never_visible=True)
    second = {o.name for o in bpy.data.collections["Never Visible"].objects}
    check("never_visible_exact", "target" in first and "target" not in second, (first, second))


def never_visible_adds_no_path():
    """Linking into "Never Visible" changes nothing anyone sees: the collection is
    excluded in every view layer, so an object whose own collection the user then
    excludes is not drawn through it."""
    scene = new_scene()
    own = bpy.data.collections.new("Own")
    scene.collection.children.link(own)
    box("target", (3, -1, 0), (4, 1, 1), own)
    update()
    report = os.path.join(WORK, "never_visible_path.json")
    bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1, link_never_visible=True)
    never = bpy.data.collections["Never Visible"]
    linked = "target" in never.objects
    scene.view_layers[0].layer_collection.children["Own"].exclude = True
    update()
    check("never_visible_no_path", linked and not drawn("target")
          and "target" not in bpy.context.view_layer.objects,
          (linked, drawn("target"), [c.name for c in bpy.data.objects["target"].users_collection]))
    excluded = all(vl.layer_collection.children["Never Visible"].exclude for vl in scene.view_layers)
    check("never_visible_excluded_everywhere", excluded, "")


def dangling_collections():
    """Addresses of the collections the scene's children and its view layers' layer
    collections point to that are no datablock of ``bpy.data`` any more (freed).
    Pointer values only: nothing in a freed collection is read by the comparison."""
    scene = bpy.context.scene
    kept = {c.as_pointer() for c in bpy.data.collections} | {scene.collection.as_pointer()}
    held = [c.as_pointer() for c in scene.collection.children]
    stack = [vl.layer_collection for vl in scene.view_layers]
    while stack:
        lc = stack.pop()
        held.append(lc.collection.as_pointer())
        stack.extend(lc.children)
    return sorted({hex(p) for p in held if p not in kept})


def undo_after_collect():
    """Undo right after "Collect Never Visible" (then redo) leaves no view layer
    pointing at a freed collection, and takes back exactly the analysis's collection.
    Blender's memfile undo keeps in place every datablock that did not change between
    the two steps it moves across and knows nothing of changes made after the last
    push: the two moves below leave the scene unchanged, so without an undo step of
    its own the new collection is freed under a scene that still links it (a crash,
    or Python reading it as a bare ID).  Run in a process of its own (a crash here
    must not hide the other cases' results)."""
    scene = new_scene()
    scene.view_layers.new("Other")
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    bpy.ops.ed.undo_push(message="scene")
    for x in (5.0, 6.0):                                 # edits that leave the scene as it is, a step each
        bpy.data.objects["target"].location.x = x
        update()
        bpy.ops.ed.undo_push(message=f"move to {x}")
    report = os.path.join(WORK, "undo_after_collect.json")
    r = bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1, link_never_visible=True)
    collected = sorted(o.name for o in bpy.data.collections["Never Visible"].objects)
    bpy.ops.ed.undo()
    update()
    after_undo = dangling_collections(), sorted(bpy.data.collections.keys())
    check("undo_after_collect_no_dangling", r == {"FINISHED"} and collected == ["target"]
          and after_undo == ([], []), (r, collected, after_undo))
    check("undo_after_collect_keeps_last_edit", bpy.data.objects["target"].location.x == 6.0,
          bpy.data.objects["target"].location.x)
    bpy.ops.ed.redo()
    update()
    never = bpy.data.collections.get("Never Visible")
    check("redo_after_collect_no_dangling", dangling_collections() == [] and never is not None
          and sorted(o.name for o in never.objects) == ["target"]
          and all("Never Visible" in vl.layer_collection.children for vl in bpy.context.scene.view_layers),
          (dangling_collections(), never and sorted(o.name for o in never.objects)))
