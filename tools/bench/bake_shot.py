"""A baked shot headless (bpy from PyPI): the bake's time and size, and playback frame by frame.

    .venv/bin/python tools/bench/bake_shot.py [SCENE] [--frames N] [--render eevee,workbench] [--size 640x360]

Builds the add-on's zip and installs it into an isolated user folder (as the Blender tests
do), builds the sample scene in bpy, keys the scene camera on the scene's camera path (the
first ``--frames`` frames; ``gui_playback.key_camera``), bakes the shot (Bake Shot, timed),
and steps through it (``scene.frame_set`` then Blender's update, each timed) with Use Baked
Shot off and on.  Headless the bake hides everywhere (``hide_viewport``), so the update
here is that channel's, not the camera view's of a window (``gui_playback.py``).  Prints
one JSON object: bake seconds (per frame), the stored text's size, the objects hidden a
frame, the frame change off and on (median ms) and the bake's apply (median ms, objects
changed per frame).

``--render`` bakes at ``--size`` (the bake holds for its render size only) and, per engine,
bakes again with that engine (its rule) and renders ``RENDER_FRAMES`` frames of the shot
spread over it at that size, once as it is and once with the frame's baked set hidden from the render
(``hide_render``, as a final render would take the bake; set and cleared by this tool),
and reports per engine the median render time (as it is: the faster of two renders), the
largest peak resident memory of the process during a render (``VmHWM`` reset before each)
and the pixels that differ beyond the renderer's own run-to-run noise (the two renders
as it is).

Inside Blender (``python tools/bench/bake_shot.py --inside ZIP WORK SCENE FRAMES ENGINES SIZE``) it is the run
itself.
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
    ap.add_argument("--render", default="", help="engines to render with: eevee, workbench (comma-separated)")
    ap.add_argument("--size", default="640x360", help="render size for --render")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        env = {**os.environ, "BLENDER_USER_RESOURCES": str(work / "user")}
        p = subprocess.run([PYTHON, os.path.abspath(__file__), "--inside", str(build_zip(work)), str(work),
                            args.scene, str(args.frames), args.render or "-", args.size], env=env, capture_output=True,
                           text=True)
        line = next((ln for ln in p.stdout.splitlines() if ln.startswith("BAKE_SHOT ")), None)
        if line is None:
            sys.stderr.write(f"bake_shot: no figures (rc {p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}\n")
            return 1
        out = json.loads(line[len("BAKE_SHOT "):])
        out["command"] = " ".join([sys.executable, *sys.argv])
        print(json.dumps(out, indent=1))
    return 0


RENDER_FRAMES = 4


def _peak_reset():
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def _peak():
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) * 1024 for ln in f if ln.startswith("VmHWM"))


def _render(path):
    """Render the scene camera's view into ``path``: ``(seconds, peak bytes, (h, w, 4) pixels)``."""
    import bpy
    import numpy as np
    sc = bpy.context.scene
    sc.render.filepath = path
    sc.render.image_settings.file_format = "PNG"
    _peak_reset()
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    took, peak = time.perf_counter() - t, _peak()
    img = bpy.data.images.load(path, check_existing=False)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], img.channels)
    bpy.data.images.remove(img)
    return took, peak, px


def render_figures(bake, engines, size, work):
    """Per engine: render time, peak memory and pixels changed with the frame's set hidden."""
    import bpy
    import numpy as np
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = (int(v) for v in size.split("x"))
    names = {"eevee": next(e for e in ("BLENDER_EEVEE", "BLENDER_EEVEE_NEXT")
                           if e in {i.identifier for i in sc.render.bl_rna.properties["engine"].enum_items}),
             "workbench": "BLENDER_WORKBENCH"}
    if bool(sc.occ_bake.use):
        bpy.ops.occ.bake_use()                      # the viewport's hiding off: the render reads hide_render
    frames = np.linspace(sc.frame_start, sc.frame_end, RENDER_FRAMES).round().astype(int).tolist()
    ids = bake.numbers()
    out = {}
    for name in engines:
        sc.render.engine = names[name]
        if name == "eevee":
            sc.eevee.taa_render_samples = 16
        bpy.ops.occ.bake_shot()                     # for this engine (its rule and name are in the fingerprint)
        holds = bake.STATE.status(bpy.context, bake.stored(sc)) is None
        if bool(sc.occ_bake.use):
            bpy.ops.occ.bake_use()
        rec = {"plain_s": [], "baked_s": [], "plain_peak": [], "baked_peak": [], "changed": [], "noise": 0.0,
               "hidden": []}
        for f in frames:
            sc.frame_set(f)
            hide = bake.frame_mask(bake.stored(sc).frame(f), ids)
            s0, p0, a = _render(os.path.join(work, f"{name}_{f}_a.png"))
            s0b, p0b, b = _render(os.path.join(work, f"{name}_{f}_b.png"))
            s0, p0 = min(s0, s0b), min(p0, p0b)          # (the first render of a frame may compile shaders)
            noise = float(np.abs(a - b).max())
            rec.setdefault("plain_differing", []).append(int((np.abs(a - b) > 1.0 / 255.0).any(axis=2).sum()))
            items = bpy.data.objects.values()
            for i in np.flatnonzero(hide).tolist():
                items[i].hide_render = True
            s1, p1, c = _render(os.path.join(work, f"{name}_{f}_c.png"))
            for i in np.flatnonzero(hide).tolist():
                items[i].hide_render = False
            rec["plain_s"].append(s0)
            rec["baked_s"].append(s1)
            rec["plain_peak"].append(p0)
            rec["baked_peak"].append(p1)
            rec["changed"].append(int((np.abs(c - a) > noise + 1.0 / 255.0).any(axis=2).sum()))
            rec["noise"] = max(rec["noise"], noise)
            rec["hidden"].append(int(hide.sum()))
        out[name] = {"frames": frames, "render_s_plain_median": float(np.median(rec["plain_s"])),
                     "render_s_baked_median": float(np.median(rec["baked_s"])),
                     "peak_mb_plain_max": max(rec["plain_peak"]) / 2**20,
                     "peak_mb_baked_max": max(rec["baked_peak"]) / 2**20,
                     "pixels_changed": rec["changed"], "noise": rec["noise"], "hidden": rec["hidden"],
                     "bake_holds": holds,
                     # pixels the two plain renders differ in: the renderer's own run-to-run change
                     "plain_pixels_differing": rec["plain_differing"]}
    return out


def render_keys_figures(sc):
    """Apply to Render: its time, the objects and keys it writes, a frame change with the
    keys (Use Baked Shot off: what the keys cost the viewport) and the check after an edit."""
    import bpy
    import numpy as np
    keys = sys.modules[f"{EXT}.occ_addon.render_keys"]
    t = time.perf_counter()
    bpy.ops.occ.bake_render()
    write_s = time.perf_counter() - t
    keyed = keys.keyed_objects()
    curves = sys.modules[f"{EXT}.occ_addon.kinds"].action_curves
    n_keys = sum(len(c.keyframe_points) for o in keyed
                 for c in curves(o.animation_data.action, getattr(o.animation_data, "action_slot", None)))
    frame_ms = []
    for f in range(sc.frame_start, sc.frame_end + 1):
        t = time.perf_counter()
        sc.frame_set(f)
        bpy.context.view_layer.update()
        frame_ms.append(1e3 * (time.perf_counter() - t))
    t = time.perf_counter()
    why = keys.holds(bpy.context)
    check_ms = 1e3 * (time.perf_counter() - t)
    t = time.perf_counter()
    why_scene = keys.holds(bpy.context, full=False)
    scene_check_ms = 1e3 * (time.perf_counter() - t)
    bpy.ops.occ.bake_render()
    return {"write_s": write_s, "objects": len(keyed), "keys": n_keys, "held": why is None and why_scene is None,
            "frame_change_ms_median": float(np.median(frame_ms)), "check_ms": check_ms,
            "scene_update_check_ms": scene_check_ms}


def inside(zip_path, work, scene_name, frames, engines, size):
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
    if engines:          # the bake is made for the render it is checked against (its size is in the fingerprint)
        sc.render.resolution_x, sc.render.resolution_y = (int(v) for v in size.split("x"))
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
    out["render_keys"] = render_keys_figures(sc)
    if engines:
        out["render"] = render_figures(bake, engines, size, work)
        out["render_size"] = size
    print("BAKE_SHOT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    if "--inside" in sys.argv:
        zip_arg, work_arg, scene_arg, frames_arg, engines_arg, size_arg = sys.argv[sys.argv.index("--inside") + 1:][:6]
        inside(zip_arg, work_arg, scene_arg, int(frames_arg), [e for e in engines_arg.split(",") if e != "-"],
               size_arg)
    else:
        sys.exit(outside(sys.argv[1:]))
