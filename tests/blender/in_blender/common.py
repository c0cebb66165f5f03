"""Shared by the cases run inside Blender (``tests/blender/cases.py``): the results, a
small scene (a camera at (-10, 0, 1) looking down +X at a wall), the operators as a
user calls them, and the truth: an object-ID render (the engine's GL renderer) of
every object Blender draws from the evaluated depsgraph (instances included) as it
would draw them if the add-on hid nothing, from the scene camera at the render
resolution: no object that covers a pixel there may be hidden by the add-on
(:func:`hidden_but_seen`)."""

import io
import json
import math
import os
import sys
from contextlib import redirect_stderr

import bpy
import numpy as np

ZIP, WORK, ROOT = sys.argv[1], sys.argv[2], sys.argv[3]
EXT_ID = "occlusion_culled_viewport"
MOD = f"bl_ext.user_default.{EXT_ID}"
results = {}
sys.path.insert(0, ROOT)            # the engine, for the truth renderer (independent of the add-on's copy)


def check(name, ok, detail=""):
    results[name] = [bool(ok), str(detail)[:2000]]


def addon(module):
    return sys.modules[f"{MOD}.occ_addon.{module}"]


# --- scenes ---------------------------------------------------------------------------

def cube_mesh(name, lo=(-0.5, -0.5, -0.5), hi=(0.5, 0.5, 0.5)):
    """A closed box mesh spanning [lo, hi] in its own coordinates."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
         (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(v, [], f)
    mesh.update()
    return mesh


def box(name, lo, hi, coll=None):
    """A box object spanning [lo, hi] (unit cube mesh, placed by location and scale)."""
    obj = bpy.data.objects.new(name, cube_mesh(name))
    (coll or bpy.context.scene.collection).objects.link(obj)
    obj.location = [(a + b) / 2 for a, b in zip(lo, hi, strict=True)]
    obj.scale = [b - a for a, b in zip(lo, hi, strict=True)]
    return obj


def new_scene():
    """Camera at (-10, 0, 1) looking down +X at 320x180; a wall at x 0..0.5."""
    bpy.ops.wm.read_homefile(use_empty=True)          # keeps preferences: the add-on stays on
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (-10.0, 0.0, 1.0)
    cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    scene.occ.source = "CAMERA"
    box("wall", (0, -6, -2), (0.5, 6, 6))
    return scene


def update():
    bpy.context.view_layer.update()


def analyzed_objects(name):
    """occ.analyze of frame 1 into WORK/<name>.json: its per-object entries."""
    report = os.path.join(WORK, f"{name}.json")
    bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=1)
    with open(report) as f:
        return json.load(f)["objects"]


def cull():
    """occ.cull, its result, and the reports (errors become RuntimeError in scripts)."""
    err = io.StringIO()
    with redirect_stderr(err):
        try:
            r = bpy.ops.occ.cull()
        except RuntimeError as e:
            r = str(e)
    update()
    return r, err.getvalue()


def hidden_by_addon(name):
    o = bpy.data.objects[name]
    return bool(o.occ_culled) and o.hide_viewport


def drawn(name):
    update()
    return bpy.data.objects[name].visible_get()


# --- the truth ----------------------------------------------------------------------

GEOMETRY = {"MESH", "CURVE", "SURFACE", "FONT", "META"}


def _mesh(ob):
    me = ob.to_mesh()
    if me is None:
        ob.to_mesh_clear()
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    me.calc_loop_triangles()
    v = np.zeros(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", v)
    f = np.zeros(len(me.loop_triangles) * 3, np.int32)
    me.loop_triangles.foreach_get("vertices", f)
    ob.to_mesh_clear()
    return v.reshape(-1, 3).astype(np.float64), f.reshape(-1, 3).astype(np.int64)


def truth_camera(scene, depsgraph):
    """The scene camera, built here on its own: rotation from the world matrix's
    quaternion (scale and mirroring dropped: a mirrored image shows the same
    objects), Blender's own projection."""
    from core import Camera
    cam = scene.camera
    world = cam.matrix_world.to_quaternion().to_matrix().to_4x4()
    world.translation = cam.matrix_world.translation
    r = scene.render
    w, h = int(r.resolution_x * r.resolution_percentage / 100), int(r.resolution_y * r.resolution_percentage / 100)
    proj = cam.calc_matrix_camera(depsgraph, x=w, y=h, scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
    return Camera.from_matrices(np.array(world.inverted()), np.array(proj)), (w, h)


def seen_names():
    """Names of the objects (instancers for their instances) that cover a pixel of
    the scene camera's view when nothing the add-on hid is hidden."""
    from core import Scene
    from core.gl import GLRenderer
    session = addon("session").SESSION
    objs = bpy.data.objects
    hidden = np.zeros(len(objs), bool)
    objs.foreach_get("hide_viewport", hidden)
    culled = np.zeros(len(objs), bool)
    objs.foreach_get("occ_culled", culled)
    session.applying = True                   # our own showing: the add-on's handler must not record it
    try:
        objs.foreach_set("hide_viewport", hidden & ~culled)
        for i in np.flatnonzero(culled):
            objs[int(i)].update_tag(refresh={"OBJECT", "DATA", "TIME"})
        if len(objs):
            objs[0].hide_viewport = bool(objs[0].hide_viewport)
        update()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        names, meshes, mats = [], [], []
        for inst in depsgraph.object_instances:
            ob = inst.object
            if ob.type not in GEOMETRY or (not inst.is_instance and not inst.show_self):
                continue
            owner = inst.parent.original.name if inst.is_instance and inst.parent else ob.original.name
            v, f = _mesh(ob)
            if len(f) and np.all(np.isfinite(v)):
                m = np.array(inst.matrix_world, dtype=np.float64)
                if np.all(np.isfinite(m)):
                    names.append(owner)
                    meshes.append((v, f))
                    mats.append(m)
        camera, (w, h) = truth_camera(bpy.context.scene, depsgraph)
    finally:
        objs.foreach_set("hide_viewport", hidden)
        if len(objs):
            objs[0].hide_viewport = bool(hidden[0])
        update()
        session.applying = False
    if not names:
        return set()
    scene = Scene.from_arrays([str(i) for i in range(len(names))], meshes, np.arange(len(names)), np.array(mats))
    r = GLRenderer(scene, w, h)
    try:
        seen = r.visible_truth(camera)
    finally:
        r.release()
    return {names[i] for i in np.flatnonzero(seen)}


def hidden_but_seen():
    """Objects the add-on hides (in either channel) that cover a pixel: must be empty."""
    return sorted(n for n in seen_names() if n in bpy.data.objects
                  and (bpy.data.objects[n].occ_culled or bpy.data.objects[n].occ_view_culled))


def promise(name):
    bad = hidden_but_seen()
    check(name, not bad, bad)


def keyframes(obj, at):
    for frame, loc in at:
        obj.location = loc
        obj.keyframe_insert("location", frame=frame)


def gn_instancer(obj, at, source=None):
    """A geometry-nodes modifier that keeps the mesh and adds one cube instance at ``at``
    (local), or one instance of object ``source`` (Object Info, its own geometry)."""
    ng = bpy.data.node_groups.new("scatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n = ng.nodes
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    pts, cube = n.new("GeometryNodePoints"), n.new("GeometryNodeMeshCube")
    inst, join = n.new("GeometryNodeInstanceOnPoints"), n.new("GeometryNodeJoinGeometry")
    pts.inputs["Count"].default_value = 1
    pts.inputs["Position"].default_value = at
    ng.links.new(pts.outputs["Points"], inst.inputs["Points"])
    if source is None:
        ng.links.new(cube.outputs["Mesh"], inst.inputs["Instance"])
    else:
        info = n.new("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = source
        info.inputs["As Instance"].default_value = True
        ng.links.new(info.outputs["Geometry"], inst.inputs["Instance"])
    ng.links.new(gin.outputs[0], join.inputs[0])
    ng.links.new(inst.outputs["Instances"], join.inputs[0])
    ng.links.new(join.outputs[0], gout.inputs[0])
    mod = obj.modifiers.new("scatter", "NODES")
    mod.node_group = ng


def hide_flags():
    objs = bpy.data.objects
    out = np.zeros(len(objs), dtype=bool)
    objs.foreach_get("hide_viewport", out)
    return out


def hidden_by_addon_any():
    return [o.name for o in bpy.data.objects if o.occ_culled and o.hide_viewport]
