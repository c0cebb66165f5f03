"""An engine scene (``core.Scene``) as Blender objects, in bulk: one mesh per
distinct engine mesh (shared meshes stay shared), one object per node."""

import bpy
import mathutils
import numpy as np


def build_scene(scene, collection=None, limit=None):
    """Replace every object of the current file with ``scene``'s objects (the first
    ``limit`` of them, in the scene's order, when given)."""
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    meshes = []
    for i, (v, f) in enumerate(scene.meshes):
        me = bpy.data.meshes.new(f"mesh{i}")
        me.vertices.add(len(v))
        me.vertices.foreach_set("co", v.astype(np.float32).ravel())
        me.loops.add(f.size)
        me.loops.foreach_set("vertex_index", f.astype(np.int32).ravel())
        me.polygons.add(len(f))
        me.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
        me.polygons.foreach_set("loop_total", np.full(len(f), 3, dtype=np.int32))
        me.update()
        meshes.append(me)
    coll = collection or bpy.context.scene.collection
    n = len(scene.names) if limit is None else min(limit, len(scene.names))
    for name, m, mat in zip(scene.names[:n], scene.mesh_of[:n], scene.matrices[:n], strict=True):
        o = bpy.data.objects.new(name, meshes[m])
        o.matrix_world = mathutils.Matrix(mat.tolist())
        coll.objects.link(o)


def view3d():
    """``(window, area, region)`` of the first 3D viewport of the open windows."""
    import bpy
    for win in bpy.context.window_manager.windows:
        for area in win.screen.areas:
            if area.type == "VIEW_3D":
                region = next(r for r in area.regions if r.type == "WINDOW")
                return win, area, region
    raise RuntimeError("no 3D viewport")


def drive_in_window(run, results, path, interval):
    """Drive the generator ``run()`` from a timer in a real window (it yields where Blender
    must process events before it goes on); then write ``results`` (with the traceback of
    a failure under "error") as JSON to ``path`` and quit Blender."""
    import json
    import traceback

    steps = []

    def tick():
        if not steps:
            steps.append(run())
        try:
            next(steps[0])
            return interval
        except StopIteration:
            pass
        except Exception:
            results["error"] = traceback.format_exc()
        with open(path, "w") as f:
            json.dump(results, f, indent=1)
        bpy.ops.wm.quit_blender()
        return None

    bpy.app.timers.register(tick, first_interval=1.0)
