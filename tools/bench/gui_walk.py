"""Live mode while the user walks, in a real Blender window (Debian's Blender 3.4 under Xvfb):

    .venv/bin/python tools/bench/gui_walk.py [SCENE] [--seconds 20] [--speed 1.4]   (-small: the small variant)

runs Blender in an Xvfb window with this checkout as a legacy add-on (as ``tests/gui``
does), loads the sample scene, and walks the viewport along the scene's camera path at a
constant pace of wall time (``--speed`` scene units a second; a timer sets the view at every event-loop turn), once with
live mode off and once with it on.  Counts the frames Blender drew (a draw handler of the
3D view), the time each draw of the 3D view took (from its PRE_VIEW to its POST_PIXEL
handler), the objects drawn per frame, live mode's own time on the main thread (its
timer's ticks) and the live passes that landed, and prints one JSON object.  A pass
that held Blender's main thread shows as fewer frames with live on.

Inside Blender (``--python tools/bench/gui_walk.py -- OUT_JSON SCENE SECONDS SPEED``) it is the walk itself.
"""

import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ADDON = "occlusion_culled_viewport"


def outside(argv):
    """Set up a Blender profile with the add-on, run the walk in a window, print its figures."""
    import argparse
    import pathlib
    import tempfile

    sys.path.insert(0, ROOT)
    from tests.gui.window import blender_env, run_in_window

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="city-small")
    ap.add_argument("--seconds", type=float, default=20.0, help="of walking, each of live off and on")
    ap.add_argument("--speed", type=float, default=1.4,
                    help="scene units a second of wall time along the path (1.4: a walk in metres)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as work:
        work = pathlib.Path(work)
        env = blender_env(work)
        out = work / "walk.json"
        argv = [str(out), args.scene, str(args.seconds), str(args.speed)]
        rc, log = run_in_window(env, os.path.abspath(__file__), argv, screen="1280x720")
        if not out.exists():
            print(f"no results (rc {rc}):\n{log[-3000:]}", file=sys.stderr)
            return 1
        print(out.read_text())
    return 0


def inside(out_path, scene_name, seconds, speed):
    import bpy
    import mathutils
    import numpy as np

    sys.path.insert(0, os.path.join(ROOT, "tools"))
    from blender_scene import build_scene, drive_in_window, view3d

    results = {"scene": scene_name, "seconds": seconds, "speed": speed, "blender": bpy.app.version_string}

    def run():
        bpy.ops.preferences.addon_enable(module=ADDON)
        core = sys.modules[f"{ADDON}.core"]
        live = sys.modules[f"{ADDON}.occ_addon.live"]
        sess = sys.modules[f"{ADDON}.occ_addon.session"].SESSION
        import sample_scenes
        name, small = (scene_name[:-6], True) if scene_name.endswith("-small") else (scene_name, False)
        scene = core.load_scene(str(sample_scenes.scene_path(name, small=small)))
        frames = sample_scenes.default_camera_path(name, small=small)["frames"]
        eyes = np.array([f["eye"] for f in frames], dtype=float)
        length = float(np.linalg.norm(np.diff(eyes, axis=0), axis=1).sum())
        seconds_walked = min(seconds, length / speed)
        build_scene(scene)
        results.update(objects=len(scene), triangles=int(scene.triangle_counts.sum()), path_length=length)
        win, area, region = view3d()
        space = area.spaces.active
        space.overlay.show_floor = False
        space.shading.type = "SOLID"
        rv3d = space.region_3d
        rv3d.view_perspective = "PERSP"
        space.clip_start, space.clip_end = 0.1, 600.0
        ctx = {"window": win, "area": area, "region": region}
        objs = bpy.data.objects
        drawn = []

        draw_ms, began, drawn_tris = [], [], []
        tris = dict(zip(scene.names, scene.triangle_counts.tolist(), strict=True))

        def pre():
            if bpy.context.region_data == rv3d:
                began[:] = [time.perf_counter()]

        def count():
            if bpy.context.region_data == rv3d:
                if began:
                    draw_ms.append(1e3 * (time.perf_counter() - began[0]))
                # (visible_in_viewport_get reads no object drawn while the add-on's local view is
                # entered on 3.4: its bits are stale; the base's, through the view layer, are not)
                shown = [o.name for o in objs if o.visible_get(view_layer=win.view_layer, viewport=space)]
                drawn.append(len(shown))
                drawn_tris.append(sum(tris.get(n, 0) for n in shown))

        # live mode's own time on the main thread: its timer's ticks (reads, landing, hiding)
        ticks = []
        plain_tick = live._tick

        def timed_tick():
            t = time.perf_counter()
            try:
                return plain_tick()
            finally:
                ticks.append(1e3 * (time.perf_counter() - t))
        live._tick = timed_tick

        def view_at(u):
            """The path's view at ``u`` in [0, 1] (linear between its frames)."""
            x = u * (len(frames) - 1)
            k = min(int(x), len(frames) - 2)
            w = x - k
            a, b = frames[k], frames[k + 1]
            mix = [[(1 - w) * p + w * q for p, q in zip(a[key], b[key], strict=True)]
                   for key in ("eye", "target", "up")]
            return core.Camera.look_at(*mix).view

        def walk(on):
            handle = bpy.types.SpaceView3D.draw_handler_add(count, (), "WINDOW", "POST_PIXEL")
            handle_pre = bpy.types.SpaceView3D.draw_handler_add(pre, (), "WINDOW", "PRE_VIEW")
            drawn.clear()
            rv3d.view_matrix = mathutils.Matrix(view_at(0.0).tolist())
            before = sess.version
            if on:
                with bpy.context.temp_override(**ctx):
                    live.start(bpy.context)
                t = time.perf_counter()
                while sess.version == before and time.perf_counter() - t < 300.0:   # the first pass, at rest
                    yield
            drawn.clear()
            drawn_tris.clear()
            draw_ms.clear()
            ticks.clear()
            start = time.perf_counter()
            landed_at_start = sess.version
            counts_at_start = dict(live.COUNTS)
            state = {"done": False}

            def step():
                walked = time.perf_counter() - start
                u = min(walked * speed / length, 1.0)
                if walked >= seconds_walked:
                    state["done"] = True
                    return None
                rv3d.view_matrix = mathutils.Matrix(view_at(u).tolist())
                area.tag_redraw()
                return 0.0

            bpy.app.timers.register(step, first_interval=0.0)
            while not state["done"]:
                yield
            took = time.perf_counter() - start
            bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
            bpy.types.SpaceView3D.draw_handler_remove(handle_pre, "WINDOW")
            tick_ms = list(ticks)
            if on:
                with bpy.context.temp_override(**ctx):
                    live.stop(bpy.context)
                    bpy.ops.occ.restore()
            return {"frames": len(drawn), "fps": len(drawn) / took,
                    "objects_drawn_mean": float(np.mean(drawn)) if drawn else None,
                    "triangles_drawn_mean": float(np.mean(drawn_tris)) if drawn_tris else None,
                    "draw_ms_median": float(np.median(draw_ms)) if draw_ms else None,
                    "draw_s_total": float(np.sum(draw_ms)) / 1e3,
                    "live_ticks": len(tick_ms), "live_tick_s_total": float(np.sum(tick_ms)) / 1e3,
                    "live_tick_ms_max": float(np.max(tick_ms)) if tick_ms else 0.0,
                    "passes_landed_walking": sess.version - landed_at_start,
                    "passes_landed": sess.version - before,
                    "live_passes_walking": {k: v - counts_at_start.get(k, 0) for k, v in live.COUNTS.items()}}

        results["live_off"] = yield from walk(False)
        results["live_on"] = yield from walk(True)

    drive_in_window(run, results, out_path, 0.05)


if __name__ == "__main__":
    if "--" in sys.argv and "bpy" in sys.modules:
        a = sys.argv[sys.argv.index("--") + 1:]
        inside(a[0], a[1], float(a[2]), float(a[3]))
    else:
        sys.exit(outside(sys.argv[1:]))
