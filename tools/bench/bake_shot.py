"""A baked shot headless (bpy from PyPI): the bake's time and size, and playback frame by frame.

    .venv/bin/python tools/bench/bake_shot.py [SCENE] [--frames N]      (-small: the small variant)

Builds the add-on's zip and installs it into an isolated user folder (as the Blender tests
do), builds the sample scene in bpy, keys the scene camera on the scene's camera path (the
first ``--frames`` frames; ``gui_playback.key_camera``), bakes the shot (Bake Shot, timed),
and steps through it (``scene.frame_set`` then Blender's update, each timed) with Use Baked
Shot off and on.  Headless the bake hides everywhere (``hide_viewport``), so the update
here is that channel's, not the camera view's of a window (``gui_playback.py``).  Prints
one JSON object: bake seconds (per frame), the stored text's size, the objects hidden a
frame, the frame change off and on (median ms) and the bake's apply (median ms, objects
changed per frame).

Inside Blender (``python tools/bench/bake_shot.py --inside ZIP WORK SCENE FRAMES``) it is the run itself.
"""

import json
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXT = "bl_ext.user_default.occlusion_culled_viewport"


def outside(argv):
    import argparse
    import pathlib
    import subprocess
    import tempfile

    sys.path.insert(0, ROOT)
    from tests.blender.harness import PYTHON, build_zip

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="city-small")
    ap.add_argument("--frames", type=int, default=90, help="path frames baked and played (from the first)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        env = {**os.environ, "BLENDER_USER_RESOURCES": str(work / "user")}
        p = subprocess.run([PYTHON, os.path.abspath(__file__), "--inside", str(build_zip(work)), str(work),
                            args.scene, str(args.frames)], env=env, capture_output=True, text=True)
        line = next((ln for ln in p.stdout.splitlines() if ln.startswith("BAKE_SHOT ")), None)
        if line is None:
            sys.stderr.write(f"bake_shot: no figures (rc {p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}\n")
            return 1
        out = json.loads(line[len("BAKE_SHOT "):])
        out["command"] = " ".join([sys.executable, *sys.argv])
        print(json.dumps(out, indent=1))
    return 0


def inside(zip_path, scene_name, frames):
    import bpy
    import numpy as np

    sys.path.insert(0, ROOT)
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    sys.path.insert(0, os.path.join(ROOT, "tools", "bench"))
    from blender_scene import build_scene
    from gui_playback import key_camera

    import core
    import sample_scenes
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    bake = sys.modules[f"{EXT}.occ_addon.bake"]
    small = scene_name.endswith("-small")
    name = scene_name[:-len("-small")] if small else scene_name
    scene = core.load_scene(str(sample_scenes.scene_path(name, small=small)))
    build_scene(scene)
    sc = bpy.context.scene
    sc.occ.source = "CAMERA"
    path = sample_scenes.default_camera_path(name, small=small)["frames"][:frames]
    key_camera(sc, path, core)
    sc.frame_set(1)
    bpy.context.view_layer.update()
    t = time.perf_counter()
    bpy.ops.occ.bake_shot()
    bake_s = time.perf_counter() - t
    b = sc.occ_bake
    out = {"scene": scene_name, "objects": len(scene), "triangles": int(scene.triangle_counts.sum()),
           "frames": sc.frame_end - sc.frame_start + 1, "bake_s": bake_s,
           "bake_s_per_frame": bake_s / (sc.frame_end - sc.frame_start + 1), "summary": b.summary,
           "stored_bytes": {"hidden": len(b.hidden), "cameras": len(b.cameras), "held": len(b.held)},
           "blender": bpy.app.version_string}
    for on in (False, True):
        if bool(b.use) != on:
            bpy.ops.occ.bake_use()
        frame_ms, apply_ms, changed, hidden = [], [], [], []
        for f in range(sc.frame_start, sc.frame_end + 1):
            t = time.perf_counter()
            sc.frame_set(f)
            bpy.context.view_layer.update()
            frame_ms.append(1e3 * (time.perf_counter() - t))
            if on:
                apply_ms.append(bake.STATE.apply_ms)
                changed.append(bake.STATE.changed)
                hidden.append(sum(1 for o in bpy.data.objects if o.occ_culled))
        run = {"frame_change_ms_median": float(np.median(frame_ms))}
        if on:
            run.update(apply_ms_median=float(np.median(apply_ms)), changed_median=float(np.median(changed)),
                       hidden_mean=float(np.mean(hidden)))
        out["use_on" if on else "use_off"] = run
    bpy.ops.occ.bake_use()
    print("BAKE_SHOT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    if "--inside" in sys.argv:
        zip_arg, _work, scene_arg, frames_arg = sys.argv[sys.argv.index("--inside") + 1:][:4]
        inside(zip_arg, scene_arg, int(frames_arg))
    else:
        sys.exit(outside(sys.argv[1:]))
