"""Live mode (occ_addon/live.py): re-culls on every change, survives undo and reload, and
guards the scene camera's motion between passes."""

import io
import math
import os
import threading
import time
from contextlib import redirect_stderr

import bpy

from .common import (
    WORK,
    addon,
    box,
    check,
    cull,
    drawn,
    hidden_but_seen,
    hidden_by_addon,
    hidden_by_addon_any,
    new_scene,
    promise,
    seen_names,
    update,
)


def ticks(live, n=2):
    """``n`` live ticks, each pass begun landed as the next tick would (headless: no timers)."""
    for _ in range(n):
        live._tick()
        live.settle()


def live_follows_changes():
    """Live mode re-culls on every change, survives undo and file load."""
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    live = addon("live")
    live.DEBOUNCE_S = 0.0
    live.start(bpy.context)
    ticks(live)
    hid = hidden_by_addon("target")
    bpy.data.objects["wall"].location.z = -20.0          # the occluder moves away
    update()
    ticks(live)
    check("live_occluder_moved_reculls", hid and drawn("target"), (hid, drawn("target")))
    promise("live_moved_truth")
    bpy.data.objects["wall"].location.z = 0.0
    update()
    ticks(live)
    hid = hidden_by_addon("target")
    bpy.data.objects["target"].occ_never_cull = True
    ticks(live)
    check("live_never_cull_reculls", hid and drawn("target"), (hid, drawn("target")))
    bpy.data.objects["target"].occ_never_cull = False
    ticks(live)
    # the settings have no update callbacks (bpy 4.2's exit crash): live mode polls them
    keep = bpy.data.collections.new("Keep")
    bpy.context.scene.collection.children.link(keep)
    keep.objects.link(bpy.data.objects["target"])
    update()
    ticks(live)
    hid = hidden_by_addon("target")
    bpy.context.scene.occ.exclude_collection = keep        # no depsgraph update, no callback
    ticks(live)
    check("live_settings_reculls", hid and drawn("target"), (hid, drawn("target")))
    bpy.context.scene.occ.exclude_collection = None
    ticks(live)
    bpy.ops.ed.undo_push(message="a")
    bpy.data.objects["wall"].location.y = 20.0
    bpy.ops.ed.undo_push(message="b")
    err = io.StringIO()
    try:
        with redirect_stderr(err):
            bpy.ops.ed.undo()
            update()
            ticks(live, 3)
        ok = "Error" not in err.getvalue() and bpy.context.scene.occ.live \
            and bpy.app.timers.is_registered(live._tick)
    except Exception as e:  # the ReferenceError of the issue
        ok = False
        err.write(repr(e))
    bpy.data.objects["wall"].location.z = -20.0
    update()
    ticks(live)
    check("live_survives_undo", ok and drawn("target"), (ok, err.getvalue()[-500:], drawn("target")))
    path = os.path.join(WORK, "live.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    state = (bpy.context.scene.occ.live, bpy.app.timers.is_registered(live._tick))
    check("live_reload_flag_matches_timer", state[0] == state[1], state)
    live.stop(bpy.context)
    bpy.ops.occ.restore()


def camera_moves_between_ticks():
    """Live from the scene camera while it moves (playback): every frame, before it is
    drawn, the hidden set either still holds for the new view (its envelope) or is
    shown; a pass every few frames (the live timer's) hides again.  The same walk with
    the hidden set left as it was shows a visible object hidden: the check can fail."""
    def build():
        scene = new_scene()
        scene.render.resolution_x, scene.render.resolution_y = 160, 90
        bpy.data.objects.remove(bpy.data.objects["wall"])
        for k in range(-6, 7):                           # a row of pillars with gaps
            box(f"pillar{k}", (0, 2.0 * k - 0.6, -2), (0.5, 2.0 * k + 0.6, 6))
        for k in range(-12, 13):                         # targets behind them, seen through the gaps in turn
            box(f"target{k}", (4, 1.0 * k - 0.2, 0), (4.4, 1.0 * k + 0.2, 1))
        cam = scene.camera
        edit = bpy.context.preferences.edit
        before, edit.keyframe_new_interpolation_type = edit.keyframe_new_interpolation_type, "LINEAR"
        for frame, y in ((1, -4.0), (41, 4.0)):
            cam.location = (-10.0, y, 1.0)
            cam.keyframe_insert("location", frame=frame)
        edit.keyframe_new_interpolation_type = before
        scene.frame_set(1)
        update()
        return scene

    session, cameras = addon("session"), addon("cameras")
    for guarded in (True, False):
        scene = build()
        scene.occ.live = guarded                          # the flag only: headless there is no timer
        camera, display = cameras.scene_camera(bpy.context)
        session.SESSION.cull(bpy.context, camera, display, fresh=True, restart=True, envelope=session.AT_REST)
        hid_any = bool(hidden_by_addon_any())
        bad = []
        for f in range(2, 42):
            scene.frame_set(f)
            update()
            wrong = hidden_but_seen()
            if wrong:
                bad.append((f, wrong))
            if guarded and f % 5 == 0:                     # the live timer's pass
                camera, display = cameras.scene_camera(bpy.context)
                session.SESSION.cull(bpy.context, camera, display, envelope=session.AT_REST)
        scene.occ.live = False
        bpy.ops.occ.restore()
        if guarded:
            check("camera_moves_guarded_no_visible_hidden", hid_any and not bad, (hid_any, bad[:3]))
        else:
            check("camera_moves_unguarded_would_hide_visible", bool(bad), "")


def camera_set_after_motion_holds():
    """Live from the scene camera: a set made at frame 1, the camera flies on (the set
    goes at the next frame), comes to rest, and a pass there hides again: that set stands
    at the next frame of the resting camera.  The camera's guard once watched the camera
    only while something was hidden, measured the resting camera against the one it saw
    last, frames back, took the flight for one step and let the new set go at once."""
    scene = new_scene()
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    for k in range(-6, 7):                               # pillars before the wall: much is hidden
        box(f"pillar{k}", (0, 2.0 * k - 0.6, -2), (0.5, 2.0 * k + 0.6, 6))
    cam = scene.camera
    edit = bpy.context.preferences.edit
    before, edit.keyframe_new_interpolation_type = edit.keyframe_new_interpolation_type, "LINEAR"
    for frame, y in ((1, -4.0), (11, 4.0)):             # flies until frame 11, then rests
        cam.location = (-10.0, y, 1.0)
        cam.keyframe_insert("location", frame=frame)
    edit.keyframe_new_interpolation_type = before
    scene.frame_set(1)
    update()
    session, cameras = addon("session"), addon("cameras")
    scene.occ.live = True                                # the flag only: headless there is no timer

    def pass_here():
        camera, display = cameras.scene_camera(bpy.context)
        session.SESSION.cull(bpy.context, camera, display, fresh=True, restart=True, envelope=session.AT_REST)
        return hidden_by_addon_any()

    def frame(f):
        time.sleep(0.06)                                 # frames as playback shows them, not at once
        scene.frame_set(f)
        update()

    first = pass_here()
    for f in range(2, 16):
        frame(f)
    gone = not hidden_by_addon_any()
    at_rest = pass_here()
    frame(16)
    kept = hidden_by_addon_any()
    wrong = hidden_but_seen()
    scene.occ.live = False
    bpy.ops.occ.restore()
    check("camera_set_after_motion_holds", bool(first) and gone and bool(at_rest) and kept == at_rest
          and not wrong, (len(first), gone, len(at_rest), len(kept), wrong[:3]))


def ortho_camera_set_holds_its_envelope():
    """Live from an orthographic scene camera (the parallel envelope at rest): a pass hides
    crates close behind the wall and keeps one far behind it (a camera turned 8 degrees sees
    it past the wall's edge); the set stands against renders of the camera turned 3 and 8
    degrees either way (inside the rest envelope's 10: the guard lets such a set stand),
    and the far crate is seen at 8 (the case is real)."""
    scene = new_scene()
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    cam = scene.camera
    cam.data.type, cam.data.ortho_scale = "ORTHO", 30.0
    cam.data.clip_start, cam.data.clip_end = 0.1, 200.0
    for k in range(-4, 5):
        box(f"crate{k}", (1.0, 1.2 * k - 0.4, 0.0), (1.8, 1.2 * k + 0.4, 2.0))
    box("deep", (60.0, -1.0, 0.0), (62.0, 1.0, 2.0))
    update()
    session, cameras = addon("session"), addon("cameras")
    scene.occ.live = True                                # the flag only: headless there is no timer
    camera, display = cameras.scene_camera(bpy.context)
    session.SESSION.cull(bpy.context, camera, display, fresh=True, restart=True, envelope=session.AT_REST)
    hidden = hidden_by_addon_any()
    crates = sum(f"crate{k}" in hidden for k in range(-4, 5))
    yaw = cam.rotation_euler[2]
    wrong, deep_seen = {}, False
    for deg in (-8.0, -3.0, 3.0, 8.0):                   # the set stays on screen (headless: no guard timer)
        cam.rotation_euler[2] = yaw + math.radians(deg)
        update()
        names = seen_names()
        wrong[deg] = sorted(n for n in names if n in hidden)
        deep_seen |= abs(deg) == 8.0 and "deep" in names
    cam.rotation_euler[2] = yaw
    scene.occ.live = False
    bpy.ops.occ.restore()
    check("ortho_camera_set_holds_its_envelope", crates >= 5 and "deep" not in hidden and deep_seen
          and not any(wrong.values()), (crates, sorted(hidden), deep_seen, wrong))


def live_cut_is_the_engines_camera_cut():
    """A live pass starts fresh after a camera cut as the engine defines it
    (``core.camera.camera_cut``: 3 degrees, 1 % of the scene, a projection change), or
    after the display's size changed; a smaller turn keeps the strategy's memory."""
    from core import Camera
    live = addon("live")
    base = Camera.look_at((-10.0, 0.0, 1.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0), 60.0, 16 / 9, 0.1, 100.0)

    def turned(deg, fov=60.0):
        a = math.radians(deg)
        target = (-10.0 + 10.0 * math.cos(a), 10.0 * math.sin(a), 1.0)
        return Camera.look_at((-10.0, 0.0, 1.0), target, (0.0, 0.0, 1.0), fov, 16 / 9, 0.1, 100.0)

    display = (320, 180)
    got = {"none": live._is_cut(None, base, display),
           "turn_2": live._is_cut((base, display), turned(2.0), display),
           "turn_5": live._is_cut((base, display), turned(5.0), display),
           "lens": live._is_cut((base, display), turned(0.0, fov=50.0), display),
           "display": live._is_cut((base, display), base, (640, 360))}
    check("live_cut_is_the_engines_camera_cut",
          got == {"none": True, "turn_2": False, "turn_5": True, "lens": True, "display": True}, got)


def passes_land_only_unchanged():
    """A live pass runs beside the interface (begun in one tick, landed in a later one):
    it lands only if nothing changed meanwhile.  An occluder moved away, the hidden
    object deleted, or an undo between the two: the pass hides nothing and nothing
    fails; the next pass decides.  Landed as it was begun, the same pass hides (the
    check can fail)."""
    live, session = addon("live"), addon("session")

    def begun():
        new_scene()
        box("target", (3, -1, 0), (4, 1, 1))
        update()
        live.DEBOUNCE_S = 0.0
        live.start(bpy.context)
        for _ in range(3):                               # the view recorded, then a pass at rest begun
            if live._tick() is None or session.SESSION.pending is not None:
                break
        return session.SESSION.pending is not None and not hidden_by_addon_any()

    got = {}
    got["begun"] = begun()
    got["landed"] = (live.settle(), hidden_by_addon("target"))
    # the set changed what is hidden: its update is the one the next set during motion must pay for
    last = session.SESSION.last
    got["update_measured"] = last.changed > 0 and live.LOOP.update_ms == last.blender_ms
    # a landed pass left nothing for Blender's next update to report (a figure written to
    # the scene would: a window evaluates it after the pass, and the bus would call it
    # the user's change, dropping the next pass in flight); nor does a Cull click
    changes = live.WATCH.changes
    bpy.context.view_layer.update()
    bpy.ops.occ.cull()
    bpy.context.view_layer.update()
    got["quiet"] = live.WATCH.changes - changes
    # leaving the envelope shows everything as the add-on's own change: no edit announced
    # (a pass in flight may land; motion passes do not wait for rest)
    live.leave()
    bpy.context.view_layer.update()
    got["left_quiet"] = (live.WATCH.changes - changes, hidden_by_addon_any(), live.WATCH.dirty_at)
    live.stop(bpy.context)
    bpy.ops.occ.restore()

    got["moved_begun"] = begun()
    bpy.data.objects["wall"].location.z = -20.0          # the occluder moves away meanwhile
    update()
    got["moved"] = (live.settle(), hidden_by_addon_any(), hidden_but_seen())
    ticks(live)
    got["moved_next"] = (drawn("target"), hidden_but_seen())
    live.stop(bpy.context)

    got["deleted_begun"] = begun()
    bpy.data.objects.remove(bpy.data.objects["target"], do_unlink=True)
    got["deleted"] = (live.settle(), hidden_by_addon_any())
    ticks(live)
    live.stop(bpy.context)

    got["undone_begun"] = begun()
    bpy.ops.ed.undo_push(message="before")
    bpy.data.objects["wall"].location.y = 20.0
    bpy.ops.ed.undo_push(message="moved")
    err = io.StringIO()
    with redirect_stderr(err):
        bpy.ops.ed.undo()
        got["undone"] = (live.settle(), session.SESSION.pending is None)
        ticks(live)
    got["undone_next"] = ("Error" not in err.getvalue(), hidden_but_seen())
    live.stop(bpy.context)
    bpy.ops.occ.restore()
    want = {"begun": True, "landed": (True, True), "update_measured": True, "quiet": 0, "left_quiet": (0, [], None),
            "moved_begun": True, "moved": (False, [], []),
            "moved_next": (True, []), "deleted_begun": True, "deleted": (False, []),
            "undone_begun": True, "undone": (False, True), "undone_next": (True, [])}
    check("live_passes_land_only_unchanged", got == want, got)


def live_keeps_no_set_made_for_another_view():
    """Live turned on after a Cull click from the scene camera (made for no envelope: it
    holds for its own view only), the camera moved since: what the click hid is shown
    before any pass lands, also when live's first pass is dropped (the jump since live's
    last look counts as the motion's step, so the pass at rest does not hold at once).
    The click's set kept instead hides an object the camera sees (the check can fail)."""
    live = addon("live")
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    live.DEBOUNCE_S = 0.0
    live.start(bpy.context)
    ticks(live)                                       # live looked at the view once
    live.stop(bpy.context)
    bpy.ops.occ.restore()
    r, _ = cull()                                     # a Cull click, live off: the target hidden
    hid = hidden_by_addon("target")
    scene.camera.location = (3.5, -8.0, 0.5)          # beside the wall: the target in plain view
    scene.camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    update()
    kept = {"stale_before_live": hidden_but_seen()}
    live.start(bpy.context)
    for _ in range(3):
        live._tick()
        kept[f"tick_{len(kept)}"] = hidden_but_seen()
        live.settle()
        kept[f"settled_{len(kept)}"] = hidden_but_seen()
    live.stop(bpy.context)
    bpy.ops.occ.restore()
    stale = kept.pop("stale_before_live")
    check("live_keeps_no_set_made_for_another_view",
          r == {"FINISHED"} and hid and stale == ["target"] and not any(kept.values()),
          (r, hid, stale, kept, dict(live.COUNTS)))


def shown_again_after_an_unseen_edit():
    """An object a Cull click hid is edited while hidden (no evaluation reports it: it is
    not evaluated), moved in front of the wall by its mesh alone.  Live mode then starts
    from a view the click's set does not hold for: everything is shown (the add-on's own
    change, its reports ignored) and a pass at rest runs.  That pass reads the object as
    it is now, so it stays drawn; its geometry cached from before the edit (behind the
    wall) would hide it again (the check can fail)."""
    live = addon("live")
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    r, _ = cull()
    hid = hidden_by_addon("target")
    target = bpy.data.objects["target"]
    for v in target.data.vertices:                      # in front of the wall, by its mesh alone
        v.co.x -= 6.0
    target.data.update()
    scene.camera.location.y += 0.05                     # the click's set holds for its own view only
    update()
    live.DEBOUNCE_S = 0.0
    landed = live.COUNTS["landed"]
    live.start(bpy.context)
    for _ in range(8):                                  # until a pass at rest has landed
        live._tick()
        live.settle()
        if live.COUNTS["landed"] > landed:
            break
    passes = live.COUNTS["landed"] - landed
    seen = hidden_but_seen()
    drawn_now = drawn("target")
    live.stop(bpy.context)
    bpy.ops.occ.restore()
    check("live_shown_again_after_an_unseen_edit", r == {"FINISHED"} and hid and passes and drawn_now and not seen,
          (r, hid, passes, drawn_now, seen, dict(live.COUNTS)))


def edits_show_the_set_on_screen():
    """A Cull click's hidden set (live mode off) stops holding at an edit that can uncover
    what it hides: the set is shown by the timer the edit's handler registers (called by
    hand here, as the window runs it before the next redraw).  A selection of what is drawn
    keeps it (a hidden object made active does not, beside a small or a large selection);
    so does a frame change that moves nothing.  An eye clicked (the wall's, its
    collection's, a second light's) is, as a selection, a change of the scene alone; so is
    a material override set on the view layer.  Each step fails on a set left standing."""
    live = addon("live")
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    cam2 = bpy.data.objects.new("cam2", bpy.data.cameras.new("cam2"))
    scene.collection.objects.link(cam2)
    cam2.location, cam2.rotation_euler = (-10.0, 0.0, 1.0), (math.pi / 2, 0.0, -math.pi / 2)
    update()
    wall = bpy.data.objects["wall"]
    out = {}

    def after(label, change, hidden_after):
        """Cull, make ``change``, run the timer: the target hidden as ``hidden_after``,
        and nothing hidden that the truth sees."""
        if not hidden_by_addon("target"):
            cull()
        first = hidden_by_addon("target")
        change()
        update()
        if live.WATCH.leaving:
            live._leave_timer()
        out[label] = (first, hidden_by_addon("target"), hidden_but_seen())
        return first and hidden_by_addon("target") == hidden_after and not out[label][2]

    def move_wall(dz):
        wall.location.z += dz

    def engine(name):
        scene.render.engine = name

    eevee = scene.render.engine
    def active(name):
        bpy.context.view_layer.objects.active = None if name is None else bpy.data.objects[name]

    ok = [after("selection", lambda: bpy.data.objects["wall"].select_set(True), True)]
    bpy.data.objects["wall"].select_set(False)
    # the hidden target made active (an outliner click, a script; headless it hides with
    # the monitor flag, which Blender does not let a selection reach): shown
    ok += [after("hidden target made active", lambda: active("target"), False)]
    active(None)
    # ... with a large selection beside it (the check reads every object's records in bulk)
    crowd = [box(f"crowd{k}", (-30 - k % 50, -6 + k // 50 * 0.25, 0), (-29.9 - k % 50, -5.9 + k // 50 * 0.25, 0.1))
             for k in range(2001)]
    update()
    for o in crowd:
        o.select_set(True)
    ok += [after("hidden target made active beside 2,001 selected", lambda: active("target"), False)]
    active(None)
    for o in crowd:
        bpy.data.objects.remove(o)
    ok += [after("frame, nothing animated", lambda: scene.frame_set(scene.frame_current + 1), True),
          after("wall moved away", lambda: move_wall(50.0), False)]
    move_wall(-50.0)
    # an eye clicked is a change of the scene alone (a selection's kind of update)
    ok += [after("wall hidden by its eye", lambda: wall.hide_set(True), False)]
    wall.hide_set(False)
    walls = bpy.data.collections.new("walls")
    scene.collection.children.link(walls)
    walls.objects.link(wall)
    scene.collection.objects.unlink(wall)
    layer_walls = bpy.context.view_layer.layer_collection.children["walls"]
    ok += [after("the wall's collection hidden by its eye", lambda: setattr(layer_walls, "hide_viewport", True),
                 False)]
    layer_walls.hide_viewport = False
    # under scene lights: a light shown by its eye casts new shadows, the rule's words the same
    lamps = []
    for name, at in (("lamp", (-10.0, 0.0, 5.0)), ("lamp2", (-10.0, 2.0, 5.0))):
        lamp = bpy.data.objects.new(name, bpy.data.lights.new(name, "POINT"))
        scene.collection.objects.link(lamp)
        lamp.location = at
        lamps.append(lamp)
    update()
    lamps[1].hide_set(True)
    ok += [after("a second light shown by its eye", lambda: lamps[1].hide_set(False), False)]
    for lamp in lamps:
        bpy.data.objects.remove(lamp)
    # the view layer's material override made see-through (EEVEE draws it on every object)
    glassy = bpy.data.materials.new("glassy")
    glassy.diffuse_color = (1.0, 1.0, 1.0, 0.3)
    layer = bpy.context.view_layer
    ok += [after("a see-through material override", lambda: setattr(layer, "material_override", glassy), False)]
    layer.material_override = None
    ok += [after("wall deleted", lambda: bpy.data.objects.remove(wall), False)]
    wall = box("wall", (0, -6, -2), (0.5, 6, 6))            # a new wall for the next steps
    ok += [after("render engine", lambda: engine("CYCLES"), False)]
    engine(eevee)
    cam = scene.camera
    ok += [after("scene camera moved", lambda: setattr(cam, "location", (-10.0, 0.05, 1.0)), False),
           after("scene camera switched", lambda: setattr(scene, "camera", cam2), False),
           after("render size", lambda: setattr(scene.render, "resolution_x", 200), False)]
    scene.camera = cam
    scene.render.resolution_x = 320

    def undo_to_a_click():
        """Undo to data saved while a click's set was hidden (a set nobody recorded now)."""
        bpy.ops.ed.undo_push(message="culled")
        bpy.ops.occ.restore()
        bpy.ops.ed.undo_push(message="restored")
        bpy.ops.ed.undo()

    def edit_then_undo():
        """An edit whose timer has not run yet, then an undo (one step: the emitter's
        delete and its undo): the timer shows what the restored data hides."""
        bpy.ops.ed.undo_push(message="culled")
        bpy.data.objects["target"].location.x += 0.0
        update()
        bpy.ops.ed.undo_push(message="edited")
        bpy.ops.ed.undo()

    ok += [after("undo to a click's hiding", undo_to_a_click, False),
           after("an edit, then an undo before the timer", edit_then_undo, False)]
    bpy.ops.occ.restore()
    check("edits_show_the_set_on_screen", all(ok), out)


def render_thread_announcements_ignored():
    """Blender announces a render job's frames from the render's own thread: the handlers
    read and write nothing there (a show is a write of Blender data beside the render).
    The render job is stood in for (``session.rendering``: none runs headless; a real one
    is ``tests/gui``'s).  With one running, a frame change from another thread leaves a
    Cull click's set and schedules nothing; with none (a script that drives bpy from a
    thread of its own), the same call is an edit naming nothing and shows the set, as it
    does from the main thread (the check can fail each way)."""
    live, handlers, session = addon("live"), addon("handlers"), addon("session")
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()

    def announce():
        handlers.on_frame_change(scene, None)
        handlers.on_depsgraph_update(scene, bpy.context.evaluated_depsgraph_get())

    def from_thread():
        worker = threading.Thread(target=announce)
        worker.start()
        worker.join()

    out = {}
    for label, call, job in (("a render's thread", from_thread, True), ("a script's thread", from_thread, False),
                             ("the main thread", announce, False)):
        if live.WATCH.leaving:              # a show an earlier step (or case) left pending runs first
            live._leave_timer()
        cull()
        first = hidden_by_addon("target")
        real = session.rendering
        session.rendering = (lambda: True) if job else real
        try:
            call()
        finally:
            session.rendering = real
        scheduled = live.WATCH.leaving
        if scheduled:
            live._leave_timer()
        out[label] = (first, scheduled, hidden_by_addon("target"))
    bpy.ops.occ.restore()
    check("render_thread_announcements_ignored",
          out == {"a render's thread": (True, False, True), "a script's thread": (True, True, False),
                  "the main thread": (True, True, False)}, out)
