"""Time the add-on's kinds of pass headless (bpy from PyPI), on a sample scene:

    .venv/bin/python tools/bench/measure_passes.py [SCENE] [--frames N]

Registers the add-on from this checkout (as tools/bench/live_pass.py does), builds
SCENE (default ``city``) as Blender objects, then times along its camera path:
a live pass after a small view change (caches trusted, temporal memory kept), a
fresh pass (what a Cull click does: the strategy starts fresh and every object
the add-on hides is checked against its data), and the tags an undo costs.
Prints medians in ms.
"""

import argparse
import os
import sys
import time

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tools"))
import live_pass  # noqa: E402
from blender_scene import build_scene  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="city")
    ap.add_argument("--frames", type=int, default=20)
    args = ap.parse_args()
    addon = live_pass.load_addon()
    core = sys.modules[f"{live_pass.PKG}.core"]
    session = sys.modules[f"{live_pass.PKG}.occ_addon.session"]
    import sample_scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = core.load_scene(str(sample_scenes.scene_path(args.scene)))
    build_scene(scene)
    ctx = bpy.context
    ctx.view_layer.update()
    cams = core.camera.cameras_from_json(sample_scenes.default_camera_path(args.scene))
    cams = [cams[i] for i in np.linspace(0, len(cams) - 1, min(args.frames, len(cams))).round().astype(int)]
    sess = session.SESSION
    sess.cull(ctx, cams[0], live_pass.DISPLAY, fresh=True)
    rows = []
    for cam in cams[1:]:
        t0 = time.perf_counter()
        sess.cull(ctx, cam, live_pass.DISPLAY, fresh=False)
        t1 = time.perf_counter()
        sess.cull(ctx, cam, live_pass.DISPLAY, fresh=True)
        t2 = time.perf_counter()
        rows.append([1e3 * (t1 - t0), 1e3 * (t2 - t1)])
    med = np.median(np.array(rows), axis=0)
    hidden = int(sum(o.occ_culled for o in bpy.data.objects))
    print(f"{args.scene}: {len(bpy.data.objects)} objects, {hidden} hidden after the last pass, "
          f"{len(rows)} views, Blender {bpy.app.version_string}")
    print(f"live pass (small view change) {med[0]:.1f} ms; fresh pass (Cull: fresh strategy, hidden objects "
          f"checked) {med[1]:.1f} ms (medians)")
    sess.shutdown()
    addon.unregister()


if __name__ == "__main__":
    main()
