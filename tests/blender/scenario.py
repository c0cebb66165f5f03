"""Runs inside real Blender (``bpy`` from PyPI), in its own process: installs the
built extension into an isolated user resource folder, builds scenes, runs the
operators and records each check.  Prints one JSON line: {check: [ok, detail]}.

Usage: python scenario.py EXTENSION.zip WORKDIR
"""

import json
import os
import sys
import traceback

import bpy

ZIP, WORK = sys.argv[1], sys.argv[2]
EXT_ID = "occlusion_culled_viewport"
results = {}


def check(name, ok, detail=""):
    results[name] = [bool(ok), str(detail)]


def box(name, lo, hi, coll=None):
    """A closed box mesh object spanning [lo, hi]."""
    import bmesh
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    (coll or bpy.context.scene.collection).objects.link(obj)
    obj.location = [(a + b) / 2 for a, b in zip(lo, hi, strict=True)]
    obj.scale = [b - a for a, b in zip(lo, hi, strict=True)]
    return obj


def build_scene():
    bpy.ops.wm.read_homefile(use_empty=True)          # keeps preferences: the add-on stays on
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (-10.0, 0.0, 1.0)
    cam.rotation_euler = (1.5707963, 0.0, -1.5707963)     # looking down +X
    box("wall", (0, -6, -2), (0.5, 6, 6))
    box("front", (-4, 1, 0), (-3, 2, 1))
    box("behind", (3, -1, 0), (4, 1, 1))
    hidden = box("user_hidden", (-4, -4, 0), (-3, -3, 1))
    hidden.hide_set(True)
    excl_coll = bpy.data.collections.new("Keep")
    scene.collection.children.link(excl_coll)
    box("excluded_behind", (3, 2, 0), (4, 3, 1), excl_coll)
    never = box("never_behind", (3, -3, 0), (4, -2, 1))
    never.occ_never_cull = True
    # a collection instance behind the wall
    src = bpy.data.collections.new("Prop")
    box("prop_part", (0, 0, 0), (0.5, 0.5, 0.5), src)
    inst = bpy.data.objects.new("prop_instance", None)
    inst.instance_type = "COLLECTION"
    inst.instance_collection = src
    inst.location = (5, 0, 0)
    scene.collection.objects.link(inst)
    # the prop source collection is excluded from the view layer (a library collection)
    lc = bpy.context.view_layer.layer_collection.children.get("Prop")
    if lc is None:
        scene.collection.children.link(src)
        lc = bpy.context.view_layer.layer_collection.children["Prop"]
    lc.exclude = True
    # a heavy mesh (about 24k triangles: cut into chunks by the engine), behind the wall
    bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=96, radius=1.0, location=(6.0, 0.0, 1.5))
    heavy = bpy.context.active_object
    heavy.name = "heavy_behind"
    heavy.select_set(False)                           # the add's selection given up: a selected object
    bpy.context.view_layer.objects.active = None      # is never hidden
    scene.occ.source = "CAMERA"
    scene.occ.exclude_collection = excl_coll
    bpy.context.view_layer.update()


def visible():
    bpy.context.view_layer.update()        # visibility flags settle on the next evaluation
    return {o.name: o.visible_get() for o in bpy.data.objects if o.type in {"MESH", "EMPTY"}}


def main():
    # --- install and enable, as a user would ---------------------------------
    bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default", enable_on_install=True)
    check("installed", f"bl_ext.user_default.{EXT_ID}" in bpy.context.preferences.addons.keys(),
          list(bpy.context.preferences.addons.keys()))
    check("operators_registered", all(hasattr(bpy.ops.occ, n) for n in ("cull", "restore", "live", "analyze")))
    check("panel_registered", hasattr(bpy.types, "OCC_PT_panel"))

    build_scene()
    before = visible()
    r = bpy.ops.occ.cull()
    after = visible()
    check("cull_finished", r == {"FINISHED"}, r)
    check("behind_hidden", not after["behind"], after)
    check("wall_and_front_shown", after["wall"] and after["front"], after)
    check("user_hidden_untouched", not after["user_hidden"] and not bpy.data.objects["user_hidden"].occ_culled)
    check("excluded_never_hidden", after["excluded_behind"], after)
    check("never_cull_respected", after["never_behind"], after)
    check("instance_culled_as_unit", not after["prop_instance"], after)
    session = sys.modules[f"bl_ext.user_default.{EXT_ID}.occ_addon.session"].SESSION
    info = session.culler.build_info
    check("heavy_mesh_chunked_and_hidden", not after["heavy_behind"] and info["meshes_chunked"] == 1
          and len(session.culler.units) > len(session.culler.scene), (after, info))
    render = bpy.context.scene.render
    render.resolution_x = 400                             # another query size: a new engine
    bpy.ops.occ.cull()
    info = session.culler.build_info
    check("resized_view_keeps_chunks", info["chunkings_reused"] == 1 and info["meshes_chunked"] == 0
          and session.culler.resolution[0] != 320 and not visible()["heavy_behind"], info)
    render.resolution_x = 320
    bpy.ops.occ.cull()
    check("camera_untouched", bpy.data.objects["cam"].visible_get())
    last = session.last
    check("panel_figures", last.tested >= 6 and last.occluded >= 2 and last.ms > 0
          and not any(k.startswith("last_") for k in bpy.context.scene.occ.keys()),
          (last.tested, last.occluded, last.outside, last.ms, list(bpy.context.scene.occ.keys())))

    # --- restore brings back exactly the prior state ----------------------------
    bpy.ops.occ.restore()
    check("restore_exact", visible() == before, (visible(), before))
    check("restore_keeps_user_hidden", bpy.data.objects["user_hidden"].hide_get())

    # --- a moved object is re-culled with the cached engine -----------------------
    bpy.ops.occ.cull()
    bpy.data.objects["behind"].location = (-6, -1, 0.5)
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    check("moved_object_reappears", visible()["behind"])
    bpy.data.objects["behind"].location = (3.5, 0, 0.5)
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    check("moved_back_hidden_again", not visible()["behind"])
    engine = session.culler
    engine_build = engine.build_info
    bpy.data.objects["behind"].location = (-6, -1, 0.5)      # shown again: no rebuild for that
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    bpy.data.objects["behind"].location = (3.5, 0, 0.5)
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    check("engine_kept_while_only_moving", engine is not None and session.culler is engine
          and session.culler.build_info is engine_build and not visible()["behind"], (engine, session.culler))

    # --- a geometry edit is re-extracted: a lowered wall uncovers what it hid --------
    wall = bpy.data.objects["wall"].data
    z = [v.co.z for v in wall.vertices]
    for v in wall.vertices:
        v.co.z = min(v.co.z, -0.45)                      # the wall sinks below the floor boxes
    wall.update()
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    info = dict(session.culler.build_info)
    check("geometry_edit_rebuilds", visible()["behind"] and info["chunkings_reused"] == 1
          and info["meshes_chunked"] == 0, (visible(), info))
    bpy.ops.occ.restore()                                # hidden objects are not evaluated: show, then edit
    for v, zz in zip(wall.vertices, z, strict=True):
        v.co.z = zz
    wall.update()
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    check("geometry_edit_back", not visible()["behind"], visible())

    # --- the record survives save and reload; loading restores ------------------
    path = os.path.join(WORK, "culled.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    objs = bpy.data.objects
    shown = visible()
    check("reload_restores_culled", shown["behind"] and not objs["behind"].occ_culled, shown)
    check("reload_keeps_user_hidden", not shown["user_hidden"], shown)

    # --- analyze over 50 frames --------------------------------------------------
    scene = bpy.context.scene
    cam = scene.camera
    scene.frame_start, scene.frame_end = 1, 50
    cam.location = (-10.0, 0.0, 1.0)
    cam.keyframe_insert("location", frame=1)
    cam.location = (8.0, 0.0, 1.0)                       # ends past the wall: "behind" comes into view
    cam.keyframe_insert("location", frame=50)
    report = os.path.join(WORK, "report.json")
    before = visible()
    r = bpy.ops.occ.analyze(filepath=report, link_never_visible=True)
    check("analyze_finished", r == {"FINISHED"}, r)
    with open(report) as f:
        data = json.load(f)
    check("analyze_50_frames", len(data["frames"]) == 50 and data["frame_count"] == 50, len(data["frames"]))
    check("analyze_per_object", data["objects"]["wall"]["frames_visible"] > 0
          and 0 < data["objects"]["behind"]["frames_visible"] < 50, data["objects"].get("behind"))
    csv_path = os.path.splitext(report)[0] + ".csv"
    with open(csv_path) as f:
        rows = f.read().splitlines()
    check("analyze_csv", rows[0].startswith("object,frames_visible") and len(rows) == len(data["objects"]) + 1)
    check("analyze_leaves_scene_as_it_was", visible() == before and scene.frame_current == 1)
    never = bpy.data.collections.get("Never Visible")
    check("never_visible_collection", never is not None
          and {o.name for o in never.objects} == {n for n, o in data["objects"].items() if o["frames_visible"] == 0})

    # --- errors become reports, not tracebacks -----------------------------------
    scene.camera = None
    try:
        r = bpy.ops.occ.cull()
        check("no_camera_reported", False, r)
    except RuntimeError as e:          # bpy turns an ERROR report into RuntimeError for scripts
        check("no_camera_reported", "no camera" in str(e), e)
    scene.camera = cam
    scene.occ.source = "VIEWPORT"
    try:
        bpy.ops.occ.cull()
        check("no_viewport_reported", False)
    except RuntimeError as e:
        check("no_viewport_reported", "no 3D viewport" in str(e), e)
    try:
        bpy.ops.occ.live()
        check("live_needs_window", False)
    except RuntimeError as e:
        check("live_needs_window", "needs a window" in str(e), e)
    scene.occ.source = "CAMERA"
    flat = bpy.data.objects.new("flat_instance", None)       # a scale of 0: a singular world matrix
    flat.instance_type = "COLLECTION"
    flat.instance_collection = bpy.data.collections["Prop"]
    flat.location, flat.scale = (-2.0, 0.0, 0.0), (1.0, 1.0, 0.0)
    scene.collection.objects.link(flat)
    bpy.context.view_layer.update()
    r = bpy.ops.occ.cull()
    check("singular_instance_culled", r == {"FINISHED"} and visible()["flat_instance"], r)
    bpy.ops.occ.restore()
    for o in list(bpy.data.objects):
        if o.type == "MESH":
            bpy.data.objects.remove(o)
    try:
        bpy.ops.occ.cull()
        check("empty_scene_reported", False)
    except RuntimeError as e:
        check("empty_scene_reported", "nothing to cull" in str(e), e)

    # --- panel draw builds its layout --------------------------------------------
    check("panel_draw", draw_panel(), "")

    # --- disabling the add-on restores what it hid ------------------------------
    build_scene()
    bpy.ops.occ.cull()
    hid = not visible()["behind"]
    bpy.ops.preferences.addon_disable(module=f"bl_ext.user_default.{EXT_ID}")
    check("disable_restores", hid and visible()["behind"], hid)


class Layout:
    """Records the UILayout calls of a panel's draw(): background Blender has no
    window, so no real UILayout exists; the properties it names are checked
    against the real RNA."""

    def __init__(self, calls):
        self.calls = calls

    def __getattr__(self, name):
        def call(*args, **kwargs):
            self.calls.append((name, args, kwargs))
            if name == "prop":
                owner, prop = args[0], args[1]
                assert prop in owner.bl_rna.properties, prop
            if name == "operator":
                op = args[0].split(".")
                assert hasattr(getattr(bpy.ops, op[0]), op[1]), args[0]
            return Layout(self.calls)
        return call


def draw_panel():
    calls = []
    panel = bpy.types.OCC_PT_panel
    fake_self = type("P", (), {"layout": Layout(calls)})()
    panel.draw(fake_self, bpy.context)
    ops = {c[1][0] for c in calls if c[0] == "operator"}
    return ops == {"occ.cull", "occ.restore", "occ.live", "occ.analyze", "occ.bake_shot"}


try:
    main()
except Exception:  # report, so the pytest side shows which step broke
    check("scenario_crashed", False, traceback.format_exc())
print("OCC_RESULTS " + json.dumps(results))
