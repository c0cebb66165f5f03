"""Analyze (occ_addon/analysis.py): the report's path and progress, the never-visible
collection."""

import io
import json
import os
import subprocess
import sys
from contextlib import redirect_stdout

import bpy
import numpy as np
from mathutils import Euler

from .common import ROOT, WORK, addon, box, check, cube_mesh, drawn, keyframes, new_scene, update


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


def render_leaves_out_occluders():
    """Under the render rule (what "Collect Never Visible" asks by default) an occluder the
    render leaves out, or draws otherwise than the viewport, occludes nothing: a wall hidden
    from the render by its own flag, or by its collection's, or subdivided in the render only,
    lets the target behind it count as seen; the viewport's rule (SEEN) still finds it
    hidden, and a rendered wall still hides it."""
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    wall = bpy.data.objects["wall"]
    walls = bpy.data.collections.new("walls")
    scene.collection.children.link(walls)
    update()
    got = {}

    def never(label, rule):
        report = os.path.join(WORK, f"render_left_out_{label}.json")
        r = bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1, rule=rule, link_never_visible=True)
        got[label] = (r, "target" in bpy.data.collections["Never Visible"].objects)

    never("rendered", "RENDER")
    wall.hide_render = True
    never("own flag", "RENDER")
    never("own flag, seen rule", "SEEN")
    wall.hide_render = False
    walls.objects.link(wall)
    scene.collection.objects.unlink(wall)
    walls.hide_render = True
    never("collection", "RENDER")
    walls.hide_render = False
    sub = wall.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 0, 3
    never("subdivided in the render only", "RENDER")
    check("analyze_render_left_out_occludes_nothing",
          got == {"rendered": ({"FINISHED"}, True), "own flag": ({"FINISHED"}, False),
                  "own flag, seen rule": ({"FINISHED"}, True), "collection": ({"FINISHED"}, False),
                  "subdivided in the render only": ({"FINISHED"}, False)}, got)


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


def _homes():
    """Object name -> how many collections (scene collections included) hold it."""
    return {o.name: len(o.users_collection) for o in bpy.data.objects}


def _collect(name):
    report = os.path.join(WORK, f"{name}.json")
    return bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1, link_never_visible=True, rule="SEEN")


def never_visible_keeps_users_objects():
    """"Collect Never Visible" never leaves an object in no collection, and leaves
    alone what the user put in "Never Visible", by each route a user gets there: the
    Move operator (M) into it, an object added while it is the active collection, a
    script linking a linked duplicate into it only.  The next collecting analysis
    keeps each, the file saved and opened again holds each, and the add-on still
    unlinks what it linked once an analysis sees it."""
    scene = new_scene()
    own = bpy.data.collections.new("Own")
    scene.collection.children.link(own)
    box("hidden", (3, -1, 0), (4, 1, 1), own)            # behind the wall: collected
    box("moved", (3, 2, 0), (4, 3, 1), own)              # behind the wall too
    box("open", (-3, -2, 0), (-2, -1, 1))                # in view, before the wall
    update()
    r0 = _collect("never_visible_routes_0")
    never = bpy.data.collections["Never Visible"]
    first = sorted(o.name for o in never.objects)
    # 1. M: "moved" into "Never Visible" only (the operator's own unlink and link)
    moved = bpy.data.objects["moved"]
    for o in bpy.context.view_layer.objects:
        o.select_set(o is moved)
    bpy.context.view_layer.objects.active = moved
    props = {p.identifier for p in bpy.ops.object.move_to_collection.get_rna_type().properties}
    where = ({"collection_uid": never.session_uid} if "collection_uid" in props          # 5.x
             else {"collection_index": 1 + [c.name for c in scene.collection.children].index("Never Visible")})
    try:
        r_move = bpy.ops.object.move_to_collection(**where)
    except RuntimeError as e:                            # then as a drag in the outliner does
        r_move = str(e)
        for c in list(moved.users_collection):
            c.objects.unlink(moved)
        never.objects.link(moved)
    # 2. added while "Never Visible" is the active collection (the user includes it in
    #    the view layer to look at it: an excluded collection cannot be the active one;
    #    then excludes it again)
    layer = bpy.context.view_layer
    layer.layer_collection.children["Never Visible"].exclude = False
    layer.active_layer_collection = layer.layer_collection.children["Never Visible"]
    bpy.ops.mesh.primitive_cube_add(location=(-3, 1, 0), size=0.5)
    bpy.context.active_object.name = "added"
    layer.active_layer_collection = layer.layer_collection
    layer.layer_collection.children["Never Visible"].exclude = True
    # 3. a script: a linked duplicate of an object there, linked into it only
    dup = bpy.data.objects["hidden"].copy()
    dup.name = "duplicate"
    never.objects.link(dup)
    update()
    mine = {n: [c.name for c in bpy.data.objects[n].users_collection] for n in ("moved", "added", "duplicate")}
    before = _homes()
    r1 = _collect("never_visible_routes_1")
    after = _homes()
    lost = sorted(n for n, k in before.items() if k and not after.get(n))
    held = {o.name for o in never.objects}
    for route, name in (("move", "moved"), ("add_active", "added"), ("script_duplicate", "duplicate")):
        check(f"never_visible_route_{route}_kept",
              r0 == r1 == {"FINISHED"} and mine[name] == ["Never Visible"] and name in held
              and name not in lost and after.get(name) == 1,
              (r0, r1, r_move if route == "move" else "", mine[name], lost, sorted(held)))
    check("never_visible_routes_nothing_lost", "moved" in first and "hidden" in first and not lost,
          (first, lost))
    path = os.path.join(WORK, "never_visible_routes.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    missing = sorted(n for n in before if n not in bpy.data.objects)
    check("never_visible_routes_saved_and_opened", not missing, missing)
    # what the user linked there beside its own collection stays too; what the add-on
    # linked goes once an analysis sees it
    scene = bpy.context.scene
    never = bpy.data.collections["Never Visible"]
    never.objects.link(bpy.data.objects["open"])         # the user's, though seen
    bpy.data.objects["wall"].location.z = -20.0          # now "hidden" is seen
    update()
    r2 = _collect("never_visible_routes_2")
    held = sorted(o.name for o in never.objects)
    check("never_visible_routes_users_link_kept_ours_unlinked",
          r2 == {"FINISHED"} and "open" in held and "hidden" not in held
          and [c.name for c in bpy.data.objects["hidden"].users_collection] == ["Own"],
          (r2, held, [c.name for c in bpy.data.objects["hidden"].users_collection]))


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


# --- the camera from its keys (occ_addon/keyed_camera.py) -------------------------------------

def _keyed_cam(scene, mode="XYZ"):
    """The scene camera keyed on frames 1, 12 and 30 (location and its rotation mode's
    channels, Bezier), with a static scale and delta transforms."""
    cam = scene.camera
    cam.rotation_mode = mode
    cam.scale = (1.5, 0.8, 1.2)
    cam.delta_location = (0.2, -0.1, 0.3)
    cam.delta_scale = (1.0, 1.1, 0.9)
    if mode == "QUATERNION":
        cam.delta_rotation_quaternion = (0.98, 0.1, 0.0, 0.17)
    elif mode != "AXIS_ANGLE":
        cam.delta_rotation_euler = (0.05, -0.1, 0.2)
    poses = [(1, (-10.0, -3.0, 1.0), (1.5, 0.1, -1.4)), (12, (-9.0, 2.0, 2.0), (1.2, -0.3, -1.9)),
             (30, (-11.0, 4.0, 0.5), (1.7, 0.4, -1.2))]
    for frame, loc, rot in poses:
        cam.location = loc
        if mode == "QUATERNION":
            cam.rotation_quaternion = tuple(2.0 * v for v in Euler(rot).to_quaternion())   # not unit
            cam.keyframe_insert("rotation_quaternion", frame=frame)
        elif mode == "AXIS_ANGLE":
            q = Euler(rot).to_quaternion()
            cam.rotation_axis_angle = (q.angle, *(3.0 * v for v in q.axis))   # not unit
            cam.keyframe_insert("rotation_axis_angle", frame=frame)
        else:
            cam.rotation_euler = rot
            cam.keyframe_insert("rotation_euler", frame=frame)
        cam.keyframe_insert("location", frame=frame)
    return cam


def keyed_camera_composes():
    """The keys give Blender's own camera matrix at every frame (frames 1..34: keys,
    interpolation and extrapolation), in every rotation mode, with delta transforms, a
    rotated and scaled static parent, an F-curve modifier and time remapping."""
    kc = addon("keyed_camera")
    for mode in ("XYZ", "ZXY", "QUATERNION", "AXIS_ANGLE"):
        scene = new_scene()
        cam = _keyed_cam(scene, mode)
        if mode == "ZXY":
            rig = bpy.data.objects.new("rig", None)
            scene.collection.objects.link(rig)
            rig.location, rig.rotation_euler, rig.scale = (1.0, 2.0, -0.5), (0.1, 0.2, 0.7), (1.3, 1.3, 1.3)
            update()
            cam.parent = rig
            cam.matrix_parent_inverse = rig.matrix_world.inverted()
            fc = next(f for f in addon("keyed_camera")._fcurves(cam) if f.data_path == "location")
            fc.modifiers.new("NOISE").strength = 0.5
            scene.render.frame_map_old, scene.render.frame_map_new = 100, 70
        update()
        keys = kc.probe(scene, kc.evaluate_frame(scene, 1), False)
        worst = 0.0
        for f in range(1, 35):
            scene.frame_set(f)
            blender = np.array(cam.matrix_world)
            worst = max(worst, float(np.abs(keys.matrix_world(f) - blender).max()) if keys else np.inf)
        check(f"keyed_camera_composes_{mode.lower()}", worst <= 1e-5 * 20, (mode, worst))


def _probe_after(change, lights_count=False):
    """probe() on the keyed camera's scene after ``change(scene, cam)``: None or the keys."""
    kc = addon("keyed_camera")
    scene = new_scene()
    cam = _keyed_cam(scene)
    target = box("target", (3, -1, 0), (4, 1, 1))
    change(scene, cam, target)
    update()
    return kc.probe(scene, kc.evaluate_frame(scene, 1), lights_count)


def _driver(scene, cam, target):
    cam.driver_add("location", 2).driver.expression = "frame / 10"


def _parent_keyed(scene, cam, target):
    rig = bpy.data.objects.new("rig", None)
    scene.collection.objects.link(rig)
    cam.parent = rig
    keyframes(rig, [(1, (0.0, 0.0, 0.0)), (30, (0.0, 0.0, 3.0))])


def _light(scene, cam, target):
    lamp = bpy.data.objects.new("lamp", bpy.data.lights.new("lamp", "POINT"))
    scene.collection.objects.link(lamp)
    keyframes(lamp, [(1, (0.0, 0.0, 5.0)), (30, (2.0, 0.0, 5.0))])


def _empty(scene, cam, target):
    e = bpy.data.objects.new("marker_empty", None)
    scene.collection.objects.link(e)
    keyframes(e, [(1, (0.0, 0.0, 5.0)), (30, (2.0, 0.0, 5.0))])


def _instancer(scene, cam, target):
    coll = bpy.data.collections.new("kit")
    coll.objects.link(cube_mesh_object("kit_box"))
    e = bpy.data.objects.new("kit_instance", None)
    e.instance_type, e.instance_collection = "COLLECTION", coll
    scene.collection.objects.link(e)
    keyframes(e, [(1, (5.0, 0.0, 0.0)), (30, (5.0, 3.0, 0.0))])


def cube_mesh_object(name):
    return bpy.data.objects.new(name, cube_mesh(name))


def _empty_moves_mesh(scene, cam, target):
    """An empty that instances nothing may move, but not one a mesh follows (its child,
    its hook)."""
    e = bpy.data.objects.new("carrier", None)
    scene.collection.objects.link(e)
    target.parent = e
    keyframes(e, [(1, (0.0, 0.0, 0.0)), (30, (0.0, 5.0, 0.0))])


def _empty_hooks_mesh(scene, cam, target):
    e = bpy.data.objects.new("hook", None)
    scene.collection.objects.link(e)
    target.modifiers.new("hook", "HOOK").object = e
    keyframes(e, [(1, (3.0, 0.0, 0.0)), (30, (3.0, 5.0, 0.0))])


def _frame_handler(scene, cam, target):
    bpy.app.handlers.frame_change_pre.append(_user_handler)


def _user_handler(scene, depsgraph=None):
    pass


REFUSED = {
    "mesh_keyed": lambda s, c, t: keyframes(t, [(1, (3.5, 0.0, 0.5)), (30, (3.5, 9.0, 0.5))]),
    "wave_modifier": lambda s, c, t: t.modifiers.new("wave", "WAVE"),
    "constraint": lambda s, c, t: setattr(c.constraints.new("TRACK_TO"), "target", t),
    "driver": _driver,
    "lens_keyed": lambda s, c, t: (setattr(c.data, "lens", 35.0), c.data.keyframe_insert("lens", frame=1),
                                   setattr(c.data, "lens", 80.0), c.data.keyframe_insert("lens", frame=30)),
    "parent_keyed": _parent_keyed,
    "marker_camera": lambda s, c, t: setattr(s.timeline_markers.new("cut", frame=10), "camera", c),
    "frame_handler": _frame_handler,
    "instancer_keyed": _instancer,
    "empty_parent_of_mesh": _empty_moves_mesh,
    "empty_hooks_mesh": _empty_hooks_mesh,
}


def keyed_camera_refused():
    """Anything else that moves with time, or camera animation beyond transform keys,
    and every frame is evaluated in full; what cannot change an answer may move."""
    taken = {"plain": _probe_after(lambda s, c, t: None) is not None,
             "light_seen": _probe_after(_light) is not None,
             "empty_keyed": _probe_after(_empty) is not None}
    check("keyed_camera_taken", all(taken.values()), taken)
    refused = {}
    for name, change in REFUSED.items():
        try:
            refused[name] = _probe_after(change) is None
        finally:
            if _user_handler in bpy.app.handlers.frame_change_pre:
                bpy.app.handlers.frame_change_pre.remove(_user_handler)
    refused["light_render"] = _probe_after(_light, lights_count=True) is None
    check("keyed_camera_refused", all(refused.values()), refused)


def _analyze_frames(name, a, b):
    report = os.path.join(WORK, "keyed", f"{name}.json")
    bpy.ops.occ.analyze(filepath=report, frame_start=a, frame_end=b)
    with open(report) as f:
        data = json.load(f)
    return [tuple(fr["visible"]) for fr in data["frames"]], data["source"]["settings"].get("camera")


def keyed_camera_analysis():
    """The report from the keys is the report frame by frame (KEYED off), frame for
    frame, and says how its camera was found; a scene where a box moves too is analyzed
    frame by frame, and the box is seen once it comes out from behind the wall."""
    an = addon("analysis")
    scene = new_scene()
    for i, y in enumerate((-8, -4, 4, 8)):
        box(f"behind_{i}", (3, y - 0.5, 0), (4, y + 0.5, 1))
    keyframes(scene.camera, [(1, (-10.0, -9.0, 1.0)), (12, (-10.0, 9.0, 1.0))])
    update()
    keyed, how = _analyze_frames("keys", 1, 12)
    an.KEYED = False
    try:
        framed, how_off = _analyze_frames("frames", 1, 12)
    finally:
        an.KEYED = True
    check("keyed_camera_report_is_frames_report", keyed == framed and len(set(keyed)) > 1
          and (how, how_off) == ("keys", "frames"), (how, how_off, keyed, framed))
    runner = box("runner", (3, -0.5, 0), (4, 0.5, 1))
    keyframes(runner, [(1, (3.5, 0.0, 0.5)), (12, (3.5, 12.0, 0.5))])
    update()
    frames, how = _analyze_frames("moving", 1, 12)
    check("keyed_camera_moving_scene_frames", how == "frames" and "runner" not in frames[0]
          and any("runner" in v for v in frames), (how, frames))
