"""Run inside a real Blender window (e.g. Debian's Blender 3.4 under Xvfb):

    xvfb-run -a -s "-screen 0 1600x900x24" blender --enable-event-simulate \
        --python tools/bench/gui_benchmark.py -- OUT_DIR [SCENE]   (a sample name, -small for its small variant)

with the add-on installed as a legacy add-on (BLENDER_USER_SCRIPTS/addons/
occlusion_culled_viewport) and moderngl, glcontext and trimesh importable
(PYTHONPATH).  Loads the sample city into the scene, sets the viewport at
street level, times ``wm.redraw_timer`` with and without culling, times cull
passes as live mode runs them, saves a screenshot, writes OUT_DIR/gui.json, quits.
"""

import os
import sys
import time

import bpy
import mathutils
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # tools/: blender_scene
from blender_scene import build_scene, drive_in_window, view3d  # noqa: E402

ARGS = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = os.path.abspath(ARGS[0] if ARGS else "gui_out")
SCENE = ARGS[1] if len(ARGS) > 1 else "city"
ADDON = "occlusion_culled_viewport"
REDRAWS = 10
WARM = 3                    # redraws before the timed ones
TAB_FROM_TOP = 125          # pixels from the sidebar's top to the third tab ("Occlusion") in Blender 3.4
results = {}


def redraw_ms(win, area, region):
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.wm.redraw_timer(type="DRAW", iterations=WARM)    # Blender's update and draw caches first
        t = time.perf_counter()
        bpy.ops.wm.redraw_timer(type="DRAW", iterations=REDRAWS)
    return 1e3 * (time.perf_counter() - t) / REDRAWS


def run():
    os.makedirs(OUT, exist_ok=True)
    bpy.ops.preferences.addon_enable(module=ADDON)
    addon = sys.modules[ADDON]
    core = sys.modules[f"{ADDON}.core"]
    import sample_scenes
    name, small = (SCENE[:-6], True) if SCENE.endswith("-small") else (SCENE, False)
    scene = core.load_scene(str(sample_scenes.scene_path(name, small=small)))
    frames = sample_scenes.default_camera_path(name, small=small)["frames"]
    build_scene(scene)
    results.update(objects=len(scene), triangles=int(scene.triangle_counts.sum()))
    win, area, region = view3d()
    area.spaces.active.overlay.show_floor = False
    space = area.spaces.active
    space.shading.type = "SOLID"
    cam = frames[len(frames) // 2]
    view = core.Camera.look_at(cam["eye"], cam["target"], cam["up"]).view
    rv3d = space.region_3d
    rv3d.view_perspective = "PERSP"
    rv3d.view_matrix = mathutils.Matrix(view.tolist())
    space.clip_start, space.clip_end = 0.1, 600.0
    results["region"] = [region.width, region.height]
    results["redraw_ms_without"] = redraw_ms(win, area, region)
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.screen.screenshot(filepath=os.path.join(OUT, "before.png"))
        t = time.perf_counter()
        r = bpy.ops.occ.cull()
        results["first_cull_ms"] = 1e3 * (time.perf_counter() - t)
    s = bpy.context.scene.occ
    last = sys.modules[f"{ADDON}.occ_addon.session"].SESSION.last
    results.update(cull_result=list(r), tested=last.tested, occluded=last.occluded,
                   outside=last.outside, triangles_hidden=last.triangles_hidden)
    # the culled view without the overlay, with it, and without any of the add-on's draw
    # handlers (the redraw guard, the overlay of culled boxes and the figures: its own
    # work per redraw), interleaved twice, the faster of each (the first redraws after a
    # change of what is drawn build Blender's draw caches)
    overlay = sys.modules[f"{ADDON}.occ_addon.overlay"]
    live = sys.modules[f"{ADDON}.occ_addon.live"]         # installs the redraw guard and the overlay
    timed = {"redraw_ms_with": [], "redraw_ms_with_overlay": [], "redraw_ms_with_no_handlers": []}
    for _ in range(2):
        s.show_overlay = False
        timed["redraw_ms_with"].append(redraw_ms(win, area, region))
        s.show_overlay = True
        timed["redraw_ms_with_overlay"].append(redraw_ms(win, area, region))
        live.uninstall()
        timed["redraw_ms_with_no_handlers"].append(redraw_ms(win, area, region))
        live.install()
    results.update({k: min(v) for k, v in timed.items()})
    results["addon_ms_per_redraw"] = results["redraw_ms_with_overlay"] - results["redraw_ms_with_no_handlers"]
    results["addon_python_ms_per_redraw"] = handlers_python_ms(win, area, region, overlay)
    results["saved_ms_per_redraw"] = results["redraw_ms_without"] - results["redraw_ms_with_no_handlers"]
    space.show_region_ui = True
    ui = next((r for r in area.regions if r.type == "UI"), None)
    try:                                          # the sidebar shows the add-on's tab (Blender 4+)
        ui.active_panel_category = "Occlusion"
    except (AttributeError, TypeError):           # 3.x: click the tab (needs --enable-event-simulate)
        yield
        x, y = ui.x + ui.width - 8, ui.y + ui.height - TAB_FROM_TOP
        for value in ("PRESS", "RELEASE"):
            win.event_simulate("LEFTMOUSE", value, x=x, y=y)
        yield
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.screen.screenshot(filepath=os.path.join(OUT, "culled.png"))
    # live passes: the view moves along the path, as the live timer would cull
    session = sys.modules[f"{ADDON}.occ_addon.session"]
    cameras = sys.modules[f"{ADDON}.occ_addon.cameras"]
    passes, parts = [], []
    sess = session.SESSION
    engine = sess.culler
    for f in frames[len(frames) // 2: len(frames) // 2 + 10]:
        rv3d.view_matrix = mathutils.Matrix(core.Camera.look_at(f["eye"], f["target"], f["up"]).view.tolist())
        with bpy.context.temp_override(window=win, area=area, region=region):
            camera, display = cameras.viewport_camera(bpy.context)
            t = time.perf_counter()
            sess.cull(bpy.context, camera, display)
            passes.append(1e3 * (time.perf_counter() - t))
            t = time.perf_counter()
            cand = sess.extractor.candidates(bpy.context)
            t1 = time.perf_counter()
            sess.extractor.matrices(cand, sess.held.index)
            t2 = time.perf_counter()
            sess.worker.run(sess.culler.cull, camera)
            t3 = time.perf_counter()
            parts.append((1e3 * (t1 - t), 1e3 * (t2 - t1), 1e3 * (t3 - t2)))
    results["live_pass_ms"] = passes
    results["live_pass_candidates_ms"] = [p[0] for p in parts]
    results["live_pass_matrices_ms"] = [p[1] for p in parts]
    results["live_pass_engine_ms"] = [p[2] for p in parts]
    results["engine_rebuilt_during_live_passes"] = sess.culler is not engine
    yield from live_motion(win, area, region, rv3d, sess, frames, core)
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.occ.restore()
    results["redraw_ms_restored"] = redraw_ms(win, area, region)
    # the floor: the same viewport with every object hidden (what no culling can go below)
    objs = bpy.data.objects
    shown = np.zeros(len(objs), dtype=bool)
    objs.foreach_get("hide_viewport", shown)
    objs.foreach_set("hide_viewport", np.ones(len(objs), dtype=bool))
    objs[0].hide_viewport = True
    results["redraw_ms_nothing_drawn"] = redraw_ms(win, area, region)
    objs.foreach_set("hide_viewport", shown)
    objs[0].hide_viewport = bool(shown[0])
    results["speedup"] = results["redraw_ms_without"] / max(results["redraw_ms_with"], 1e-9)
    # as the user sees it: the overlay on, the add-on's draw handlers included
    results["speedup_with_overlay"] = results["redraw_ms_without"] / max(results["redraw_ms_with_overlay"], 1e-9)
    yield from modal_operators(win, area, region, sess, frames)
    del addon


def handlers_python_ms(win, area, region, overlay):
    """The add-on's draw handlers' own Python time per redraw of the culled view, each
    timed around its calls, overlay on: ``{name: ms}`` for the redraw guard, the
    overlay of culled boxes and the inset with the figures, and their sum ("all");
    what they make the GPU draw is in the redraw's difference."""
    live = sys.modules[f"{ADDON}.occ_addon.live"]
    names = [(live, "guard"), (overlay, "_draw_view"), (overlay, "_draw_pixel")]
    spent = dict.fromkeys((n for _, n in names), 0.0)

    def timed(name, fn):
        def call(*a):
            t = time.perf_counter()
            try:
                return fn(*a)
            finally:
                spent[name] += time.perf_counter() - t
        return call

    kept = [getattr(m, n) for m, n in names]
    live.uninstall()
    for (m, n), fn in zip(names, kept, strict=True):
        setattr(m, n, timed(n, fn))
    live.install()
    bpy.context.scene.occ.show_overlay = True
    try:
        redraw_ms(win, area, region)                # the batches made, then timed
        spent.update(dict.fromkeys(spent, 0.0))
        redraw_ms(win, area, region)
    finally:
        live.uninstall()
        for (m, n), fn in zip(names, kept, strict=True):
            setattr(m, n, fn)
        live.install()
    out = {n: 1e3 * v / (WARM + REDRAWS) for n, v in spent.items()}
    out["all"] = sum(out.values())
    return out


def live_motion(win, area, region, rv3d, sess, frames, core):
    """Live mode in the window while the view turns a few degrees a redraw: after each
    redraw and the events that follow it (the redraw guard's timer, live ticks), the
    add-on's hidden set holds for the view on screen (inside the envelope it was made
    for), or nothing is hidden."""
    live = sys.modules[f"{ADDON}.occ_addon.live"]
    ctx = {"window": win, "area": area, "region": region}
    f = frames[len(frames) // 2]
    base = core.Camera.look_at(f["eye"], f["target"], f["up"]).view
    with bpy.context.temp_override(**ctx):
        live.start(bpy.context)
    for _ in range(8):                                # at rest: the first live pass
        yield
    rested = sess.shown is not None
    held, passes_before = [], sess.version
    counts_before = dict(live.COUNTS)
    for k in range(1, 13):
        a = np.radians(2.0 * k)                        # the view turns 2 degrees a step
        turn = np.array([[np.cos(a), -np.sin(a), 0, 0], [np.sin(a), np.cos(a), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
        rv3d.view_matrix = mathutils.Matrix((base @ turn).tolist())
        with bpy.context.temp_override(**ctx):
            bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)
        yield
        with bpy.context.temp_override(**ctx):
            camera, _ = sys.modules[f"{ADDON}.occ_addon.cameras"].viewport_camera(bpy.context)
        hidden = sum(1 for o in bpy.data.objects if o.occ_culled and o.hide_viewport)
        shown = sess.shown
        held.append(hidden == 0 or (shown is not None and shown[1].holds(shown[0], camera)))
    with bpy.context.temp_override(**ctx):
        live.stop(bpy.context)
    # live mode's own counts over the turn (begun, landed, dropped and why): what to read when
    # no pass landed
    counts = {k: v - counts_before.get(k, 0) for k, v in live.COUNTS.items() if v != counts_before.get(k, 0)}
    results["live_motion"] = {"rested_with_envelope": rested, "held": held,
                              "passes": sess.version - passes_before, "counts": counts}


def modal_operators(win, area, region, sess, frames):
    """The panel's buttons run the operators modal (INVOKE_DEFAULT): a first build in
    timer steps, then the pass; analyze frame by frame, stopped by Esc."""
    ctx = {"window": win, "area": area, "region": region}
    sess.reset()                                      # the next cull builds from scratch
    with bpy.context.temp_override(**ctx):
        results["modal_cull_started"] = list(bpy.ops.occ.cull("INVOKE_DEFAULT"))
    t = time.perf_counter()
    while sess.busy and time.perf_counter() - t < 120:
        yield
    results["modal_cull"] = {"finished": sess.busy is None and sess.culler is not None,
                             "occluded": sess.last.occluded, "outside": sess.last.outside}
    with bpy.context.temp_override(**ctx):
        bpy.ops.occ.cull()                            # the same view at once: the same answer
    results["sync_cull"] = {"occluded": sess.last.occluded, "outside": sess.last.outside}
    # analyze from a scene camera, stopped by Esc after a few frames
    scene = bpy.context.scene
    cam = bpy.data.objects.new("occ_cam", bpy.data.cameras.new("occ_cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    f = frames[len(frames) // 2]
    cam.matrix_world = mathutils.Matrix(np.linalg.inv(
        sys.modules[f"{ADDON}.core"].Camera.look_at(f["eye"], f["target"], f["up"]).view).tolist())
    scene.frame_start, scene.frame_end, scene.frame_current = 1, 100000, 3
    stopped = os.path.join(OUT, "stopped.json")
    with bpy.context.temp_override(**ctx):
        results["modal_analyze_started"] = list(bpy.ops.occ.analyze("INVOKE_DEFAULT", filepath=stopped))
    yield
    x, y = region.x + region.width // 2, region.y + region.height // 2
    win.event_simulate("ESC", "PRESS", x=x, y=y)
    win.event_simulate("ESC", "RELEASE", x=x, y=y)
    yield
    results["modal_analyze_esc"] = {"busy": sess.busy, "frame": scene.frame_current,
                                    "written": os.path.exists(stopped)}
    done = os.path.join(OUT, "analyzed.json")
    with bpy.context.temp_override(**ctx):
        bpy.ops.occ.analyze("INVOKE_DEFAULT", filepath=done, frame_start=1, frame_end=12)
    t = time.perf_counter()
    while sess.busy and time.perf_counter() - t < 120:
        yield
    results["modal_analyze_done"] = {"busy": sess.busy, "frame": scene.frame_current,
                                     "written": os.path.exists(done)}


drive_in_window(run, results, os.path.join(OUT, "gui.json"), 0.3)
