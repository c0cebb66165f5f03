"""Animation playback with a baked shot, in a real Blender window (Debian's Blender 3.4 under Xvfb):

    .venv/bin/python tools/bench/gui_playback.py [SCENE] [--seconds 20] [--fps 1000]   (-small: the small variant)

runs Blender in an Xvfb window with this checkout as a legacy add-on (as ``tests/gui``
does), loads the sample scene, keys the scene camera on every frame of the scene's camera
path (frames 1..N), makes the 3D view look through it (solid shading, the camera frame
fitted to the region), bakes the shot (Bake Shot, timed) and plays the animation for
``--seconds`` of wall time from the first frame, once with Use Baked Shot off and once
on.  Playback: ``sync_mode`` NONE (every frame is drawn, none dropped) at ``--fps``
(default 1000: as fast as Blender draws; its animation timer is the only brake).
Counts per run the frames Blender drew of the camera view (a draw handler), the frames
advanced (``frame_change_post``), the time each draw of the 3D view took (its PRE_VIEW
to its POST_PIXEL handler), the frame change (``frame_change_pre`` to a
``frame_change_post`` handler after the add-on's: scene evaluation and the bake's
apply), the bake's own apply per frame and the objects it changed (its ``STATE``), and,
sampled every ``SAMPLE_S`` of wall time, the objects hidden in the view
(``occ_view_culled``), the objects and triangles drawn (``visible_get`` in the view) and
whether the hidden set is the frame's baked one.  The two runs reach different frames in
the same wall time: ``draw_ratio_off_on_common`` compares their draws over the frames both
drew.  Prints one JSON object (with any traceback Blender's console shows).

``--modal`` bakes as a click does: the operator's modal run (``INVOKE_DEFAULT``), the window
drawing between its steps.

Inside Blender (``--python tools/bench/gui_playback.py -- OUT_JSON SCENE SECONDS FPS [modal]``) it is the playback
itself.
"""

import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ADDON = "occlusion_culled_viewport"
SAMPLE_S = 0.25          # the hidden / drawn counts are taken this often (a walk of every object)
RENDER = (1280, 720)     # the render size the bake culls at (the path's 16:9)


def outside(argv):
    """Set up a Blender profile with the add-on, run the playback in a window, print its figures."""
    import argparse
    import json
    import pathlib
    import tempfile

    sys.path.insert(0, ROOT)
    from tests.gui.window import blender_env, run_in_window

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="city-small")
    ap.add_argument("--seconds", type=float, default=20.0, help="of playback, each of the bake off and on")
    ap.add_argument("--fps", type=int, default=1000, help="the scene's frame rate (sync NONE: every frame drawn)")
    ap.add_argument("--modal", action="store_true",
                    help="bake as a click does (the operator's modal run with its progress), not in one call")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp, "playback.json")
        inner = [str(out), args.scene, str(args.seconds), str(args.fps), *(["modal"] if args.modal else [])]
        rc, log = run_in_window(blender_env(pathlib.Path(tmp)), os.path.abspath(__file__), inner, screen="1280x720")
        if not out.is_file():
            sys.stderr.write(f"gui_playback: Blender wrote no figures (exit {rc}); its log ends:\n{log[-3000:]}\n")
            return 1
        results = json.loads(out.read_text())
        results["command"] = " ".join([sys.executable, *sys.argv])
        lines = log.splitlines()
        results["console_tracebacks"] = ["\n".join(lines[i:i + 12]) for i, ln in enumerate(lines)
                                         if ln.startswith("Traceback")]
        print(json.dumps(results, indent=1))
    return 0


def key_camera(scene, frames, core):
    """A scene camera keyed on frames 1..N at the path's views (its first frame's lens)."""
    import bpy
    import mathutils
    import numpy as np

    first = frames[0]
    cam = bpy.data.objects.new("path_camera", bpy.data.cameras.new("path_camera"))
    scene.collection.objects.link(cam)
    cam.data.sensor_fit = "VERTICAL"
    cam.data.angle_y = np.radians(first["fov_y_deg"])
    cam.data.clip_start, cam.data.clip_end = first["near"], first["far"]
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = RENDER
    scene.render.resolution_percentage = 100
    euler = None
    for f, c in enumerate(frames, start=1):
        view = core.Camera.look_at(c["eye"], c["target"], c["up"]).view
        m = mathutils.Matrix(np.linalg.inv(view).tolist())
        euler = m.to_euler("XYZ", euler) if euler is not None else m.to_euler("XYZ")   # no wrap between keys
        cam.location, cam.rotation_euler = m.translation, euler
        cam.keyframe_insert("location", frame=f)
        cam.keyframe_insert("rotation_euler", frame=f)
    scene.frame_start, scene.frame_end = 1, len(frames)
    return cam


def camera_scene(core, scene_name, fps):
    """The sample scene built, its path's camera keyed, the first 3D view looking through it
    (solid, the frame fitted to the region); -> (engine scene, window override of that view)."""
    import bpy
    from blender_scene import build_scene, view3d

    import sample_scenes
    name = scene_name.removesuffix("-small")
    small = name != scene_name
    scene = core.load_scene(str(sample_scenes.scene_path(name, small=small)))
    build_scene(scene)
    sc = bpy.context.scene
    key_camera(sc, sample_scenes.default_camera_path(name, small=small)["frames"], core)
    sc.render.fps, sc.render.fps_base, sc.sync_mode = fps, 1.0, "NONE"
    sc.frame_set(sc.frame_start)
    win, area, region = view3d()
    view = area.spaces.active
    view.shading.type, view.overlay.show_floor = "SOLID", False
    view.region_3d.view_perspective = "CAMERA"
    ctx = {"window": win, "area": area, "region": region}
    with bpy.context.temp_override(**ctx):
        bpy.ops.view3d.view_center_camera()
    return scene, ctx


def stats(values, name):
    import numpy as np
    return {f"{name}_median": float(np.median(values)) if values else None,
            f"{name}_mean": float(np.mean(values)) if values else None}


def inside(out_path, scene_name, seconds, fps, modal=False):
    import bpy
    import numpy as np

    sys.path.insert(0, os.path.join(ROOT, "tools"))
    from blender_scene import drive_in_window

    results = {"scene": scene_name, "seconds": seconds, "fps_setting": fps, "sync_mode": "NONE",
               "blender": bpy.app.version_string}

    def run():
        bpy.ops.preferences.addon_enable(module=ADDON)
        bake = sys.modules[f"{ADDON}.occ_addon.bake"]
        flags = sys.modules[f"{ADDON}.occ_addon.identity"].flags
        scene, ctx = camera_scene(sys.modules[f"{ADDON}.core"], scene_name, fps)
        sc, win, space = bpy.context.scene, ctx["window"], ctx["area"].spaces.active
        rv3d = space.region_3d
        results.update(objects=len(scene), triangles=int(scene.triangle_counts.sum()),
                       frame_start=sc.frame_start, frame_end=sc.frame_end)
        yield
        t = time.perf_counter()
        with bpy.context.temp_override(**ctx):
            if modal:                              # as a click: the modal run, the window drawing between steps
                done = bpy.ops.occ.bake_shot("INVOKE_DEFAULT", frame_start=sc.frame_start, frame_end=sc.frame_end)
            else:
                done = bpy.ops.occ.bake_shot(frame_start=sc.frame_start, frame_end=sc.frame_end)
        session = sys.modules[f"{ADDON}.occ_addon.session"].SESSION
        ticks = 0
        while session.busy is not None and time.perf_counter() - t < 600:
            ticks += 1
            yield
        results.update(bake_modal=modal, bake_ticks=ticks, bake_stored=bool(sc.occ_bake.hidden))
        results.update(bake_s=time.perf_counter() - t, bake_result=sorted(done),
                       bake_frames=sc.frame_end - sc.frame_start + 1, bake_summary=sc.occ_bake.summary)
        objs = bpy.data.objects
        tris = dict(zip(scene.names, scene.triangle_counts.tolist(), strict=True))
        rec = {}

        def pre_view():
            if bpy.context.region_data == rv3d:
                rec["began"] = time.perf_counter()

        def post_pixel():
            if bpy.context.region_data != rv3d:
                return
            now = time.perf_counter()
            if "began" in rec:
                rec["draw_ms"].append(1e3 * (now - rec.pop("began")))
                rec["by_frame"].setdefault(sc.frame_current, []).append(rec["draw_ms"][-1])
            rec["drawn"] += 1
            if now - rec["sampled"] < SAMPLE_S:
                return
            rec["sampled"] = now
            hidden = flags("occ_view_culled")
            rec["hidden"].append(int(hidden.sum()))
            # (not gui_walk's visible_in_viewport_get: on 3.4 it reads no object drawn in a local view)
            shown = [o.name for o in objs if o.visible_get(view_layer=win.view_layer, viewport=space)]
            rec["objects_drawn"].append(len(shown))
            rec["tris_drawn"].append(sum(tris.get(n, 0) for n in shown))
            rec["perspective"].add(rv3d.view_perspective)
            baked = bake.stored(sc)
            row = baked.frame(sc.frame_current) if baked is not None and sc.occ_bake.use else None
            if row is not None:
                rec["not_baked_set"].append(int((bake.frame_mask(row, bake.numbers()) != hidden).sum()))

        def frame_pre(_scene, _depsgraph=None):
            rec["frame_began"] = time.perf_counter()

        def frame_post(_scene, _depsgraph=None):
            rec["advanced"] += 1
            if "frame_began" in rec:
                rec["frame_ms"].append(1e3 * (time.perf_counter() - rec.pop("frame_began")))
            st = bake.STATE
            if st.apply_ms != rec["last_apply"]:          # an apply ran on this frame change
                rec["last_apply"] = st.apply_ms
                rec["apply_ms"].append(st.apply_ms)
                rec["changed"].append(st.changed)
            rec["applied"] += bool(st.applied)

        def play(on):
            if bool(sc.occ_bake.use) != on:
                with bpy.context.temp_override(**ctx):
                    bpy.ops.occ.bake_use()
            sc.frame_set(sc.frame_start)
            for _ in range(5):
                yield
            rec.clear()
            rec.update(drawn=0, advanced=0, applied=0, sampled=0.0, last_apply=bake.STATE.apply_ms, perspective=set(),
                       by_frame={},
                       **{k: [] for k in ("draw_ms", "frame_ms", "apply_ms", "changed", "hidden",
                                          "objects_drawn", "tris_drawn", "not_baked_set")})
            handles = [bpy.types.SpaceView3D.draw_handler_add(pre_view, (), "WINDOW", "PRE_VIEW"),
                       bpy.types.SpaceView3D.draw_handler_add(post_pixel, (), "WINDOW", "POST_PIXEL")]
            bpy.app.handlers.frame_change_pre.append(frame_pre)
            bpy.app.handlers.frame_change_post.append(frame_post)     # after the add-on's
            with bpy.context.temp_override(**ctx):
                bpy.ops.screen.animation_play()
            start = time.perf_counter()
            while time.perf_counter() - start < seconds:
                yield
            with bpy.context.temp_override(**ctx):
                bpy.ops.screen.animation_cancel(restore_frame=False)
            took = time.perf_counter() - start
            for h in handles:
                bpy.types.SpaceView3D.draw_handler_remove(h, "WINDOW")
            bpy.app.handlers.frame_change_pre.remove(frame_pre)
            bpy.app.handlers.frame_change_post.remove(frame_post)
            return {"wall_s": took, "frames_drawn": rec["drawn"], "fps_drawn": rec["drawn"] / took,
                    "frames_advanced": rec["advanced"], "fps_advanced": rec["advanced"] / took,
                    **stats(rec["draw_ms"], "draw_ms"), "draw_s_total": float(np.sum(rec["draw_ms"])) / 1e3,
                    **stats(rec["frame_ms"], "frame_change_ms"),
                    "applies": len(rec["apply_ms"]), "frames_applied": rec["applied"],
                    **stats(rec["apply_ms"], "apply_ms"), **stats(rec["changed"], "changed"),
                    "samples": len(rec["hidden"]), **stats(rec["hidden"], "hidden"),
                    "hidden_max": max(rec["hidden"], default=0),
                    **stats(rec["objects_drawn"], "objects_drawn"), **stats(rec["tris_drawn"], "triangles_drawn"),
                    "samples_not_baked_set": sum(1 for m in rec["not_baked_set"] if m),
                    "not_baked_set_max": max(rec["not_baked_set"], default=0),
                    "view_perspective": sorted(rec["perspective"]), "local_view": space.local_view is not None,
                    "stale": bake.STATE.stale, "known": bake.STATE.known,
                    # the panel's estimate (core/playback.py): the drawing a frame's hiding saves
                    "estimated_saved_ms": stats([x for _, x in bake.STATE.playback.samples], "m")["m_median"]
                    if on and bake.STATE.playback.samples else None,
                    "advice": bake.STATE.playback.advice() if on else None,
                    "draw_ms_by_frame": {f: float(np.median(v)) for f, v in sorted(rec["by_frame"].items())}}

        results["bake_off"] = yield from play(False)
        results["bake_on"] = yield from play(True)
        off, on = results["bake_off"], results["bake_on"]
        results["fps_ratio_on_off"] = on["fps_drawn"] / off["fps_drawn"] if off["fps_drawn"] else None
        # the runs reach different frames in the same wall time: their draws compared frame by frame
        common = sorted(set(off["draw_ms_by_frame"]) & set(on["draw_ms_by_frame"]))
        results["common_frames"] = len(common)
        results["draw_ratio_off_on_common"] = (
            float(sum(off["draw_ms_by_frame"][f] for f in common) / sum(on["draw_ms_by_frame"][f] for f in common))
            if common else None)
        with bpy.context.temp_override(**ctx):
            bpy.ops.occ.bake_use()                       # off again: everything shown
        yield
        results["after_off"] = {"hidden": int(flags("occ_view_culled").sum()),
                                "local_view": space.local_view is not None, "view_perspective": rv3d.view_perspective}
        yield from beyond_the_camera(sc, ctx, space, bake, flags)
        # Apply to Render, then a setting Blender reports to no handler (the add-on's settings
        # have no update callbacks): the window's poll removes the keys
        with bpy.context.temp_override(**ctx):
            applied = sorted(bpy.ops.occ.bake_render())
        keyed = bool(sc.occ_bake.render_keys)
        for _ in range(10):
            yield
        stood = bool(sc.occ_bake.render_keys)
        sc.occ.exclude_children = not sc.occ.exclude_children
        waited = 0
        while sc.occ_bake.render_keys and waited < 40:
            yield
            waited += 1
        results["render_keys_poll"] = {"applied": applied, "keyed": keyed, "stood": stood,
                                       "removed": not sc.occ_bake.render_keys, "turns": waited,
                                       "note": sc.occ_bake.render_note}

    def beyond_the_camera(sc, ctx, space, bake, flags):
        """A view through the camera that also draws more (a clipping region made with
        Alt+B's operator, then Quad View), or through a Local Camera of its own, or with
        shadows of its own (Solid's): the baked shot hides nothing there."""
        def hidden():
            return int(flags("occ_view_culled").sum())

        def settle(frame):
            sc.frame_set(frame)
            ctx["area"].tag_redraw()
            for _ in range(10):                          # the redraw guard's timer, the frame's apply
                yield

        with bpy.context.temp_override(**ctx):
            bpy.ops.occ.bake_use()                       # on again
        out = results["beyond_the_camera"] = {"stale": bake.STATE.stale}

        def record(label, frame):
            """At ``frame``, once settled: how many the bake hides, as ``label``."""
            yield from settle(frame)
            out[label] = hidden()

        yield from record("hidden_first", sc.frame_start + 1)
        region = ctx["region"]
        with bpy.context.temp_override(**ctx):
            out["clip_border"] = sorted(bpy.ops.view3d.clip_border(
                xmin=region.width // 4, xmax=3 * region.width // 4, ymin=region.height // 4,
                ymax=3 * region.height // 4))
        yield from record("clipped", sc.frame_start + 1)
        yield from record("clipped_next_frame", sc.frame_start + 2)
        space.region_3d.use_clip_planes = False
        yield from record("hidden_again", sc.frame_start + 3)
        with bpy.context.temp_override(**ctx):
            bpy.ops.screen.region_quadview()
        yield from record("quad", sc.frame_start + 3)
        yield from record("quad_next_frame", sc.frame_start + 4)
        with bpy.context.temp_override(**ctx):
            bpy.ops.screen.region_quadview()             # back to one region, the one drawing the view
        ctx["region"] = next(r for r in ctx["area"].regions if r.type == "WINDOW")
        yield from record("one_region", sc.frame_start + 3)
        # the view through a camera of its own (Local Camera: another picture than the
        # shot's; any object can be one, and choosing it changes nothing the bake read)
        own, shot_camera = next(o for o in sc.objects if o != sc.camera), sc.camera
        space.use_local_camera = True                    # first: else the view's camera is the scene's
        space.camera = own
        yield from record("local_camera", sc.frame_start + 3)
        yield from record("local_camera_next_frame", sc.frame_start + 4)
        space.camera = None
        space.use_local_camera = False
        out["scene_camera_kept"] = sc.camera == shot_camera
        # the view's own shading draws shadows the shot's render does not: turned on while a
        # frame's set is shown, the set goes before the next redraw, and no frame hides there
        yield from settle(sc.frame_start + 3)
        out["before_shadows"], out["shading"] = hidden(), space.shading.type
        space.shading.show_shadows = True
        ctx["area"].tag_redraw()
        for _ in range(10):                              # redraws, the guard's timer: no new frame
            yield
        out["shadows"] = hidden()
        yield from record("shadows_next_frame", sc.frame_start + 4)
        space.shading.show_shadows = False
        yield from record("shadows_off", sc.frame_start + 3)
        with bpy.context.temp_override(**ctx):
            bpy.ops.occ.bake_use()                       # off, as before
        yield

    drive_in_window(run, results, out_path, 0.05)


if __name__ == "__main__":
    if "bpy" not in sys.modules or "--" not in sys.argv:
        sys.exit(outside(sys.argv[1:]))
    out_json, scene_arg, seconds_arg, fps_arg, *rest = sys.argv[sys.argv.index("--") + 1:]
    inside(out_json, scene_arg, float(seconds_arg), int(fps_arg), modal="modal" in rest)
