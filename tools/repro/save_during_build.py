"""Saves made while the engine thread builds (real bpy): the reproducer of a crash.

    BLENDER_USER_RESOURCES=$(mktemp -d) .venv/bin/python tools/repro/save_during_build.py [OBJECTS] [SAVES]

Builds the rows scene of ``tools/bench/blender_scale.py`` (default 30,000 objects), culls once
in the window's 3D view (the add-on's own local view), then SAVES times (default 8):
adds an object (the next pass rebuilds the engine), starts the modal first steps the
way a window drives them, and saves while the engine thread builds.  The save's handler
ends the own local view through ``view3d.localview``; with the engine thread running
Python inside that operator, bpy 5.0.1 segfaulted (1 run in 3 before ``worker.quiet``).
Prints one line per save and ``SAVES_DONE`` at the end; a crash ends the process first
(run it with ``PYTHONFAULTHANDLER=1`` to see both threads).
"""

import os
import sys
import tempfile
import time

import bpy

TOOLS = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [TOOLS, os.path.join(TOOLS, "bench")]
from blender_scale import EXT_ID, build_rows  # noqa: E402
from build_extension import plain_zip  # noqa: E402


def main(objects=30_000, saves=8):
    work = tempfile.mkdtemp(prefix="occ_saves_")
    bpy.ops.extensions.package_install_files(filepath=plain_zip(os.path.join(work, "dist")),
                                             repo="user_default", enable_on_install=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    build_rows(bpy, objects, unique=False)
    scene = bpy.context.scene
    scene.occ.source, scene.occ.hide_in = "CAMERA", "VIEW"
    bpy.context.view_layer.update()
    addon = f"bl_ext.user_default.{EXT_ID}.occ_addon."
    session, worker = sys.modules[addon + "session"].SESSION, sys.modules[addon + "worker"]
    print("first cull", bpy.ops.occ.cull(), flush=True)
    for k in range(saves):
        extra = bpy.data.objects.new(f"extra{k}", bpy.data.meshes["cube"])
        scene.collection.objects.link(extra)
        extra.location = (5.0 + k, 0.0, 0.5)
        bpy.context.view_layer.update()
        steps = session.prepare_steps(bpy.context, (1280, 720))
        job = next((item for item in steps if isinstance(item, worker.Job)), None)
        building = job is not None and not job.done()
        t = time.perf_counter()
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, f"save{k}.blend"), copy=True)
        print(f"save {k}: {'while building' if building else 'after the build'}, "
              f"{time.perf_counter() - t:.2f} s", flush=True)
        steps.close()
        print("cull", bpy.ops.occ.cull(), flush=True)
    print("SAVES_DONE", flush=True)


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:]]
    main(*args)
