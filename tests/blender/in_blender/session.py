"""The engine's lifecycle (occ_addon/session.py, extract.py): identity by session id,
edits seen (reported or not), modal steps, a click's fresh answer, query and display
resolutions."""

import os
import sys

import bpy
import numpy as np

from .common import (
    WORK,
    addon,
    box,
    check,
    cube_mesh,
    cull,
    drawn,
    hidden_by_addon,
    hide_flags,
    new_scene,
    promise,
    update,
)


def wall_and_pebble(pebble_name):
    """A wall named "Wall" hiding "behind", a pebble named ``pebble_name`` off to the
    side, "target" in plain view; culled once.  Returns (wall, pebble)."""
    scene = new_scene()
    bpy.data.objects.remove(bpy.data.objects["wall"])
    wall = bpy.data.objects.new("Wall", cube_mesh("wall_mesh", (0, -6, -2), (0.5, 6, 6)))
    pebble = bpy.data.objects.new(pebble_name, cube_mesh("pebble_mesh", (0, 0, 0), (0.2, 0.2, 0.2)))
    for o in (wall, pebble):
        scene.collection.objects.link(o)
    pebble.location = (-6.0, 2.5, 0.0)
    box("target", (-3, -0.5, 0), (-2.5, 0.5, 0.5))
    box("behind", (3, -1, 0), (4, 1, 1))
    update()
    cull()
    return wall, pebble


def identity_follows_objects():
    """Caches follow objects, not names: swapped names, delete and rename."""
    wall, pebble = wall_and_pebble("Pebble")
    wall.name, pebble.name = "tmp", "Wall"
    wall.name = "Pebble"
    update()
    cull()
    check("identity_swapped_names", drawn("target") and hidden_by_addon("behind"),
          (drawn("target"), hidden_by_addon("behind")))
    promise("identity_swap_truth")
    # delete "Wall", rename "Wall.001" (a pebble) to "Wall"
    wall, pebble = wall_and_pebble("Wall.001")
    bpy.data.objects.remove(wall)
    pebble.name = "Wall"
    update()
    cull()
    check("identity_delete_rename", drawn("target") and drawn("behind"), (drawn("target"), drawn("behind")))
    promise("identity_delete_truth")


def hidden_edits():
    """Edits to an object while the add-on hides it (never reported by Blender) are
    seen by the next Cull: the geometry is checked against the data it was read from."""
    for what in ("move", "nan"):
        new_scene()
        box("target", (3, -1, 0), (4, 1, 1))
        update()
        cull()
        hid = hidden_by_addon("target")
        if what == "move":
            # unedited, a click's check of what the add-on hides finds it as read: it stays
            # hidden, not shown and hidden again (its data was fingerprinted when hidden)
            cull()
            last = addon("session").SESSION.last
            check("hidden_unedited_stays_hidden", hid and hidden_by_addon("target") and last.changed == 0,
                  (hid, hidden_by_addon("target"), last.changed))
        me = bpy.data.objects["target"].data
        co = np.zeros(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        if what == "move":
            co[:, 0] -= 8.0                               # its mesh now stands in front of the wall
        else:
            co[0] = np.nan
        me.vertices.foreach_set("co", co.ravel())
        me.update()
        update()
        r, err = cull()
        check(f"hidden_edit_{what}_seen", hid and r == {"FINISHED"} and not hidden_by_addon("target"),
              (hid, r, hidden_by_addon("target"), err[-500:]))
        promise(f"hidden_edit_{what}_truth")


def _shown_after_edit(name, hid):
    """A Cull after an edit of the hidden "target" (or of what hides it): drawn now."""
    r, err = cull()
    check(f"{name}_seen", hid and r == {"FINISHED"} and not hidden_by_addon("target"),
          (hid, r, hidden_by_addon("target"), err[-500:]))
    promise(f"{name}_truth")


def hidden_faces_edit():
    """An edit of a hidden object's faces alone (no vertex moved, as many faces as
    before) is seen by the next Cull: a second wall "inner", hidden behind the first
    with the target behind it, gets its face over the target rebuilt from the vertices
    of its other face; the first wall then moves away, and the target, now seen
    through the hole, must be drawn."""
    new_scene()
    me = bpy.data.meshes.new("inner")
    v = [(2, y, z) for y, z in ((-2, -1), (2, -1), (2, 3), (-2, 3))]        # over the target
    v += [(2, y, z) for y, z in ((-5, 4), (-3, 4), (-3, 5), (-5, 5))]        # off to one side
    me.from_pydata(v, [], [(0, 1, 2, 3), (4, 5, 6, 7)])
    me.update()
    inner = bpy.data.objects.new("inner", me)
    bpy.context.scene.collection.objects.link(inner)
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    cull()
    hid = hidden_by_addon("inner") and hidden_by_addon("target")
    me.polygons[0].vertices = (7, 6, 5, 4)          # the same quad as face 1, turned over
    me.update()
    bpy.data.objects["wall"].location.z = -20.0     # the first wall goes
    update()
    _shown_after_edit("hidden_faces_edit", hid)
    # a modifier's setting edited while hidden: an array's second copy now stands in front
    new_scene()
    target = box("target", (3, -1, 0), (4, 1, 1))
    mod = target.modifiers.new("array", "ARRAY")
    mod.count, mod.use_relative_offset = 1, False
    update()
    cull()
    hid = hidden_by_addon("target")
    mod.count, mod.use_constant_offset, mod.constant_offset_displace = 2, True, (-8.0, 0.0, 0.0)
    update()
    _shown_after_edit("hidden_modifier_edit", hid)
    # a shape key's value set by hand while hidden: the key moves the box in front
    new_scene()
    target = box("target", (3, -1, 0), (4, 1, 1))
    target.shape_key_add(name="Basis")
    key = target.shape_key_add(name="forward")
    for p in key.data:
        p.co.x -= 8.0
    key.value = 0.0
    update()
    cull()
    hid = hidden_by_addon("target")
    key.value = 1.0
    update()
    _shown_after_edit("hidden_shape_key_edit", hid)


def fast_preset_keeps_display_gaps():
    """The fast preset queries at half the display's resolution, yet hides nothing the
    display shows: a slit of one display pixel, between two pixel centres of the
    half-resolution query, still shows what stands behind it."""
    scene = new_scene()
    scene.render.resolution_x, scene.render.resolution_y = 64, 32
    cam = scene.camera
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 64.0                  # one world unit per display pixel
    cam.location = (-10.0, 0.0, 0.0)
    wall = bpy.data.objects["wall"]
    wall.location, wall.scale = (0.25, -16.0 + 0.2, 0.0), (0.5, 32.0, 40.0)   # y -32.0 .. 0.2
    box("wall2", (0.0, 0.8, -20.0), (0.5, 32.0, 20.0))      # the slit: y 0.2 .. 0.8 around a display centre
    box("target", (3.0, -2.0, -2.0), (4.0, 2.0, 2.0))
    scene.occ.preset = "fast"
    scene.occ.strategy = "stopwait"     # a query per node: with three objects the occupancy map would draw all
    update()
    r, err = cull()
    check("display_fast_preset_slit_kept", r == {"FINISHED"} and drawn("target"), (r, err[-500:]))
    promise("display_fast_preset_truth")
    bpy.data.objects["wall2"].location.y -= 0.6             # the slit closed: now it is hidden
    update()
    cull()
    check("display_fast_preset_closed_hidden", hidden_by_addon("target"), "")


def modal_steps():
    """The modal operators' steps (what a window drives from its timer; background
    mode has none, so they are driven here): stopped during the build or the
    geometry reading (Esc), nothing in the scene changed and the next Cull is
    right; an edit that lands between steps is seen by the pass that follows."""
    session, extract, analysis = addon("session"), addon("extract"), addon("analysis")
    worker = addon("worker")
    SESSION = session.SESSION
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    cull()                                         # the wall hides the target
    before = hide_flags()
    display = (320, 180)
    # a moved wall is a rebuild only with new geometry: edit the wall's mesh
    me = bpy.data.objects["wall"].data
    me.vertices[0].co.x -= 0.01
    me.update()
    update()
    steps = SESSION.prepare_steps(bpy.context, display)
    kinds = []
    for item in steps:
        kinds.append(type(item).__name__)
        if isinstance(item, worker.Job):
            break
    steps.close()                                  # Esc while the engine builds
    update()
    check("steps_cancel_build_nothing_changed",
          "Job" in kinds and np.array_equal(before, hide_flags()) and SESSION.culler is None,
          (kinds, SESSION.culler))
    r, err = cull()
    check("steps_cancel_build_then_cull", r == {"FINISHED"} and hidden_by_addon("target"), (r, err[-500:]))
    promise("steps_cancel_build_truth")

    # the wall is read, then shrunk between steps, before the build: the pass must not
    # hide the target behind the wall as it was read
    new_scene()
    for i in range(6):
        box(f"pebble{i}", (-3.0, -5.0 + i, 0.0), (-2.9, -4.9 + i, 0.1))
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    extract.STEP_S = 0.0                           # a step before every object's geometry
    try:
        steps = SESSION.prepare_steps(bpy.context, display)
        wall = bpy.data.objects["wall"]
        reads, edited = 0, False
        uid = addon("identity").ident(wall)
        for item in steps:
            if isinstance(item, worker.Job):
                item.wait()
                continue
            reads += 1
            if edited or uid not in SESSION.extractor.cache:
                continue
            # the wall is read, other objects are not yet: now the edit lands
            edited = True
            co = np.zeros(len(wall.data.vertices) * 3, np.float32)
            wall.data.vertices.foreach_get("co", co)
            co = co.reshape(-1, 3)
            co[:, 2] = np.minimum(co[:, 2], -0.49)        # the wall drops below the target
            wall.data.vertices.foreach_set("co", co.ravel())
            wall.data.update()
            update()
        # a stopped reading, too: nothing hidden, and the next pass reads what it must
        steps = SESSION.prepare_steps(bpy.context, display)
        first = next(steps, None)
        steps.close()
    finally:
        extract.STEP_S = 0.1
    r, err = cull()
    check("steps_edit_between_steps_seen", edited and reads >= 8 and first is not None and r == {"FINISHED"}
          and not hidden_by_addon("target"), (reads, first, r, hidden_by_addon("target"), err[-500:]))
    promise("steps_edit_between_steps_truth")

    # analyze stopped after three frames: the frame is back, no report written
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end, scene.frame_current = 1, 30, 7
    path = os.path.join(WORK, "stopped_analysis.json")
    steps = analysis.analysis_steps(bpy.context, list(range(1, 31)), path)
    frames_done = 0
    for item in steps:
        if not isinstance(item, worker.Job):
            frames_done += 1
            if frames_done == 3:
                break
    steps.close()
    check("steps_analyze_cancel_restores_frame",
          scene.frame_current == 7 and not os.path.exists(path), (scene.frame_current, os.path.exists(path)))


def instanced_child_edited():
    """A vertex instancer occludes with its instances; the instanced child's mesh is
    then edited smaller: the next Cull must not hide what the old instance covered
    (the instancer's cached instances are stale once an object it instances changes;
    workflow seed 640 found it with a particle-free scene like this one)."""
    new_scene()
    pts = bpy.data.meshes.new("VertPoints")
    pts.from_pydata([(-3.0, 0.0, 1.0)], [], [])
    inst = bpy.data.objects.new("VertInstancer", pts)
    bpy.context.scene.collection.objects.link(inst)
    inst.instance_type = "VERTS"
    child = box("VertChild", (-0.5, -2.5, -2.5), (0.5, 2.5, 2.5))
    child.parent = inst
    box("target", (-1.5, -0.3, 0.7), (-1.2, 0.3, 1.3))
    update()
    cull()
    hid = hidden_by_addon("target")
    me = child.data
    co = np.zeros(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    me.vertices.foreach_set("co", (co * 0.05).astype(np.float32))   # the instance shrinks to a speck
    me.update()
    update()
    r, err = cull()
    check("instanced_child_edited_seen", hid and r == {"FINISHED"} and not hidden_by_addon("target"),
          (hid, r, hidden_by_addon("target"), err[-500:]))
    promise("instanced_child_edited_truth")
    me.vertices.foreach_set("co", co)                  # full size again: it hides the target
    me.update()
    update()
    cull()
    hid = hidden_by_addon("target")
    child.display_type = "WIRE"                        # its instances are wire now: they occlude nothing
    update()
    r, err = cull()
    check("instanced_child_wire_seen", hid and r == {"FINISHED"} and not hidden_by_addon("target"),
          (hid, r, hidden_by_addon("target"), err[-500:]))
    promise("instanced_child_wire_truth")


def hair_instancer(source):
    """An emitter in front of the wall whose hair particles instance ``source`` (an
    object, or a collection) around (-4, 0, 1), and a target right behind them."""
    em = box("Emitter", (-4.1, -0.1, 0.9), (-3.9, 0.1, 1.1))
    em.modifiers.new("hair", "PARTICLE_SYSTEM")
    ps = em.particle_systems[0].settings
    ps.type, ps.count, ps.hair_length, ps.particle_size = "HAIR", 4, 0.2, 1.0
    ps.display_method = "RENDER"                       # the viewport draws the instances
    if isinstance(source, bpy.types.Collection):
        ps.render_type, ps.instance_collection = "COLLECTION", source
    else:
        ps.render_type, ps.instance_object = "OBJECT", source
    box("target", (-2.0, -0.3, 0.7), (-1.7, 0.3, 1.3))
    update()


def instance_source_deleted():
    """Hair particles instance a large box (an object, then a collection's member) that
    hides a target; the box is deleted: the next Cull must not hide the target behind
    the instances that went with it (Blender reports neither the deleted object nor a
    geometry change of the emitter; workflow seed 956 found it)."""
    for what in ("source", "member"):
        scene = new_scene()
        lib = None
        if what == "member":
            lib = bpy.data.collections.new("HairLib")
            scene.collection.children.link(lib)
        src = box(f"Hair_{what}", (4.5, 4.5, -1.5), (7.5, 7.5, 1.5), lib)     # behind the wall, aside
        hair_instancer(lib or src)
        cull()
        hid = hidden_by_addon("target")
        bpy.data.objects.remove(src)
        update()
        r, err = cull()
        check(f"instance_{what}_deleted_seen", hid and r == {"FINISHED"} and not hidden_by_addon("target"),
              (hid, r, hidden_by_addon("target"), err[-500:]))
        promise(f"instance_{what}_deleted_truth")


def click_restarts():
    """A Cull click gives a new engine's answer whatever came before (the same click,
    the same answer): live passes from other views in between leave the default
    strategy (gpu) its memory, which the click drops; an analysis starts the same way
    and goes on from what its earlier frames taught."""
    scene = new_scene()
    for k in range(12):
        box(f"b{k}", (2 + 1.5 * (k % 4), -4 + 2.5 * (k // 4), 0), (3 + 1.5 * (k % 4), -3 + 2.5 * (k // 4), 1 + k % 3))
    update()
    session = addon("session").SESSION
    cull()
    first = session.last.stats
    hidden = sorted(o.name for o in scene.objects if hidden_by_addon(o.name))
    camera, display = addon("cameras").scene_camera(bpy.context)
    cam = scene.camera
    for x in (-9.0, -8.0):                               # live passes from nearer views: memory kept
        cam.location.x = x
        update()
        camera, display = addon("cameras").scene_camera(bpy.context)
        session.cull(bpy.context, camera, display, fresh=True)
    kept = session.last.stats.fresh == 0
    cam.location.x = -10.0
    update()
    r, err = cull()
    again = sorted(o.name for o in scene.objects if hidden_by_addon(o.name))
    check("click_restarts_fresh", r == {"FINISHED"} and first.fresh == 1 and kept
          and session.last.stats.fresh == 1, (first.fresh, kept, session.last.stats, err[-300:]))
    check("click_restarts_same_answer", hidden and again == hidden, (hidden, again))
    promise("click_restarts_truth")


def engine_context_outlives_undo():
    """An undo or redo drops the engine (Blender may hand back the same ids with other
    contents); the next one is built on the engine thread's own GL context, not on a
    new one: a context made and released per engine kept memory every time
    (``tools/checks/soak.py``'s undo phase)."""
    scene = new_scene()
    for k in range(6):
        box(f"u{k}", (2 + 2.0 * k, -1, 0), (3 + 2.0 * k, 1, 1 + k % 2))
    update()
    session = addon("session").SESSION
    bpy.ops.ed.undo_push(message="boxes")
    cull()
    ctx = session.culler.renderer.ctx
    scene.objects["u0"].location.z += 0.5
    update()
    bpy.ops.ed.undo_push(message="moved")
    contexts = []
    for op in (bpy.ops.ed.undo, bpy.ops.ed.redo):
        op()
        r, err = cull()
        contexts.append((r, session.culler is not None and session.culler.renderer.ctx is ctx, err[-200:]))
    check("engine_context_outlives_undo", contexts == [({"FINISHED"}, True, "")] * 2, contexts)


def bulk_map_is_its_dict():
    """kinds.BulkMap (what each object is, whether it is dynamic: looked up in bulk)
    answers as the dict it mirrors through a seeded run of sets, re-sets, pops and
    clears, and unknown uids read UNKNOWN."""
    import random
    kinds = addon("kinds")
    rng = random.Random(7)
    table, truth, bad = kinds.BulkMap(int), {}, []
    for step in range(3000):
        uid = rng.randrange(400)
        op = rng.random()
        if op < 0.5:
            table[uid] = truth[uid] = rng.randrange(4)
        elif op < 0.8:
            if table.pop(uid, None) != truth.pop(uid, None):
                bad.append(("pop", step, uid))
        elif op < 0.801:
            table.clear()
            truth.clear()
        if step % 37 == 0:
            probe = np.array(rng.sample(range(500), 60), dtype=np.int64)
            want = np.array([truth.get(int(u), kinds.UNKNOWN) for u in probe])
            if not np.array_equal(table.codes_of(probe), want) or len(table) != len(truth):
                bad.append(("codes", step))
    check("bulk_map_is_its_dict", not bad, bad[:5])


def large_mesh_triangles_in_place():
    """A large mesh's triangles read from Blender's own array (meshes._triangles_in_place)
    are ``loop_triangles.foreach_get("vertices")``'s, triangle for triangle, on a mesh of
    quads, triangles and n-gons (its tessellation), and the in-place read is what is taken."""
    meshes = addon("meshes")
    new_scene()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=300, y_subdivisions=300, size=20)
    mesh = bpy.context.object.data
    bpy.ops.mesh.primitive_circle_add(vertices=64, fill_type="NGON", location=(30, 0, 0))
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, location=(-30, 0, 0))
    bpy.ops.object.select_all(action="SELECT")
    bpy.context.view_layer.objects.active = bpy.data.objects["Grid"]
    bpy.ops.object.join()
    mesh.calc_loop_triangles()
    n = len(mesh.loop_triangles)
    want = np.empty((n, 3), dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", want.reshape(-1))
    got = meshes._triangles_in_place(mesh, n)
    v, f = meshes.read_mesh(mesh)
    check("large_mesh_triangles_in_place", n >= meshes.RAW_TRIANGLES and got is not None
          and np.array_equal(got, want) and np.array_equal(f, want), (n, got is None))


# --- Blender's own crash, and what the add-on may do near it (issue 30) -----------------

def _hair(emitter, source):
    """A hair system on ``emitter`` that instances ``source`` (4 strands)."""
    emitter.modifiers.new("hair", "PARTICLE_SYSTEM")
    ps = emitter.particle_systems[0].settings
    ps.type, ps.count, ps.render_type, ps.instance_object = "HAIR", 4, "OBJECT", source


def hair_undo_two_layers():
    """The ingredients of Blender's crash (``../shared/repro/blender_hair_undo_two_layers.py``)
    with the add-on's operations between them: a hair system instancing an object that
    was moved, a second view layer shown in the window, the emitter deleted and the
    deletion undone, then Cull, Analyze, a live pass, frame changes and the other
    layer's evaluation.  Plain Blender does not crash on these steps (the instance
    object is not moved or tagged after the second layer is shown); a Cull click that tagged
    every object's transform (every click, in a file of several view layers; a click
    that finds the engine built reads nothing more that would evaluate it again) made
    Blender crash at the next ``frame_set``.  Run in a process of its own:
    a crash shows as the test's exit status (the old code crashed at the ``frame_set``
    after the undo, rc 139)."""
    scene = new_scene()
    emitter = box("Emitter", (-3, -1, 0), (-2, 1, 1))            # in view, before the wall
    source = box("HairSource", (-3, 2, 0), (-2, 3, 1))           # in view too: the first click
    _hair(emitter, source)                                       # hides nothing
    source.location.x += 0.5                                     # moved, in the first layer
    update()
    bpy.ops.ed.undo_push(message="build")
    layer = scene.view_layers.new("Second")
    bpy.context.window.view_layer = layer
    update()
    bpy.ops.ed.undo_push(message="view layer")
    # What every pass does first, on its own (the old code tagged every transform there;
    # the rest of a click happened to evaluate past the tags here, not in seed 843's
    # file): the candidates read for a new view layer
    SESSION = addon("session").SESSION
    SESSION.reread_transforms()
    SESSION.candidates(bpy.context)
    bpy.data.objects.remove(bpy.data.objects["Emitter"], do_unlink=True)
    bpy.ops.ed.undo_push(message="delete")
    bpy.ops.ed.undo()
    update()
    bpy.context.scene.frame_set(55)                              # every view layer's depsgraph
    clicks = [cull()[0], cull()[0]]         # the second click finds the engine built: no rebuild
    box("behind", (3, -1, 0), (4, 1, 1))    # then something the wall hides
    update()
    steps = [("undo, clicks", clicks == [{"FINISHED"}] * 2 and "Emitter" in bpy.data.objects)]
    r = cull()
    steps.append(("cull", r[0]))
    promise("hair_undo_cull_truth")
    bpy.data.objects.remove(bpy.data.objects["Emitter"], do_unlink=True)
    bpy.ops.ed.undo_push(message="delete again")
    bpy.ops.ed.undo()
    update()
    r = cull()
    steps.append(("cull after undo", r[0]))
    promise("hair_undo_cull_after_undo_truth")
    report = os.path.join(WORK, "hair_undo.json")
    steps.append(("analyze", bpy.ops.occ.analyze(filepath=report, frame_start=1, frame_end=3)))
    live = addon("live")
    live.DEBOUNCE_S = 0.0
    live.start(bpy.context)
    bpy.context.scene.camera.location.y += 0.2
    update()
    for _ in range(2):
        live._tick()
        live.settle()
    live.stop(bpy.context)
    steps.append(("live", bpy.context.scene.occ.live))
    bpy.context.scene.frame_set(55)                              # every view layer's depsgraph
    bpy.context.scene.view_layers["ViewLayer"].update()
    bpy.context.scene.frame_set(1)
    steps.append(("frames", bpy.context.scene.frame_current))
    check("hair_undo_two_layers_no_crash", steps[0][1] and steps[1][1] == steps[2][1] == steps[3][1] == {"FINISHED"},
          steps)
    promise("hair_undo_two_layers_truth")


def foreign_overrides_during_a_job():
    """Another add-on's operators, called through ``temp_override`` while the engine
    thread runs Python: Blender 4.2 and 5.0 crash at once without the add-on's guard
    (they read the override's dictionary without the GIL; ``tools/repro/override_thread_crash.py``
    shows it with a plain thread, no add-on); each call now waits for the engine's job.
    Blender 5.2 makes operators functions of their own and needs no guard."""
    import time

    new_scene()
    for i in range(20):
        box(f"b{i}", (2 + i, -1, 0), (2.5 + i, 1, 2))
    update()
    cull()                                             # the engine thread exists
    worker = addon("worker")
    ops = sys.modules["bpy.ops"]
    wrapped = "_op_call" in vars(ops)
    guarded = isinstance(vars(ops).get("_op_call"), getattr(worker, "_OperatorGuard", ()))
    session = addon("session").SESSION

    def busy(seconds):
        """Python on the engine thread: allocations and reference counts, as a build makes."""
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            junk = [{"k": i, "v": [i] * 8} for i in range(500)]
            del junk
        return True

    win = bpy.context.window_manager.windows[0]
    waited, calls = [], 0
    for k in range(12):
        job = session.worker.submit(busy, 0.15)
        ob = bpy.data.objects[f"b{k % 20}"]
        with bpy.context.temp_override(window=win, selected_objects=[ob], selected_editable_objects=[ob],
                                       active_object=ob, object=ob):
            (bpy.ops.object.duplicate, bpy.ops.object.shade_smooth, bpy.ops.object.select_all)[k % 3]()
        calls += 1
        waited.append(job.done())
    check("foreign_override_no_crash", calls == 12, calls)
    check("foreign_override_guard_where_needed", guarded == wrapped, (wrapped, guarded))
    check("foreign_override_waits_for_the_job", all(waited) or not wrapped, waited)


def edit_outside_the_layer():
    """A wall's mesh edited while the window shows a view layer that leaves the wall out
    (no evaluation reports the edit), then a new view layer that draws it: its first
    evaluation reports the wall without the geometry change.  The next pass reads the
    wall as it is now: the wall made low no longer hides the target behind it (the
    wall's old geometry would, so the check can fail)."""
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    walls = bpy.data.collections.new("Walls")
    scene.collection.children.link(walls)
    wall = bpy.data.objects["wall"]
    for c in list(wall.users_collection):
        c.objects.unlink(wall)
    walls.objects.link(wall)
    update()
    r1, _ = cull()                                        # the target hidden behind the wall
    hid = hidden_by_addon("target")
    bpy.ops.occ.restore()
    other = scene.view_layers.new("Other")
    other.layer_collection.children["Walls"].exclude = True
    bpy.context.window.view_layer = other
    update()
    r2, _ = cull()                                        # a pass in the layer without the wall
    for v in wall.data.vertices:                          # the wall made low: the target in view
        v.co.z = min(v.co.z, -1.5)
    wall.data.update()
    update()
    third = scene.view_layers.new("Third")                # a new layer: its first evaluation
    bpy.context.window.view_layer = third
    update()
    r3, _ = cull()
    check("edit_outside_the_layer_seen",
          (r1, hid, r2, r3, hidden_by_addon("target")) == ({"FINISHED"}, True, {"FINISHED"}, {"FINISHED"}, False),
          (r1, hid, r2, r3, hidden_by_addon("target")))
    promise("edit_outside_the_layer_truth")
    bpy.ops.occ.restore()


def edit_while_another_layer_shown():
    """As :func:`edit_outside_the_layer`, with no pass in the layer that leaves the wall
    out: the wall is still held by the last engine (read in the first layer) when the
    window shows a new layer, whose first evaluation reports nothing.  The wall made low
    while unwatched must be read again: behind its old shape the target would be hidden."""
    scene = new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    walls = bpy.data.collections.new("Walls")
    scene.collection.children.link(walls)
    wall = bpy.data.objects["wall"]
    for c in list(wall.users_collection):
        c.objects.unlink(wall)
    walls.objects.link(wall)
    update()
    r1, _ = cull()                                        # the target hidden behind the wall
    hid = hidden_by_addon("target")
    other = scene.view_layers.new("Other")
    other.layer_collection.children["Walls"].exclude = True
    bpy.context.window.view_layer = other                 # no pass here: the wall stays held
    update()
    for v in wall.data.vertices:                          # the wall made low: the target in view
        v.co.z = min(v.co.z, -1.5)
    wall.data.update()
    update()
    third = scene.view_layers.new("Third")                # a new layer: its first evaluation
    bpy.context.window.view_layer = third                 # reports no change
    update()
    r2, _ = cull()
    check("edit_while_another_layer_shown_seen",
          (r1, hid, r2, hidden_by_addon("target")) == ({"FINISHED"}, True, {"FINISHED"}, False),
          (r1, hid, r2, hidden_by_addon("target")))
    promise("edit_while_another_layer_shown_truth")
    bpy.ops.occ.restore()


def floor_under_the_camera():
    """Live mode's click over a large ground (its rest envelope, 0.6 % of the scene, reaches
    under the ground from 1.7 above it): the pass keeps the eyes off the ground, so a
    facade standing on the ground hides a crate behind it; the truth sees nothing hidden;
    a camera lowered under the envelope's floor leaves it, and the next click's answer
    holds for the new view."""
    scene = new_scene()
    bpy.data.objects.remove(bpy.data.objects["wall"])
    box("ground", (-250, -250, -0.2), (250, 250, 0.0))
    box("facade", (0, -6, 0), (0.3, 6, 3.2))
    box("crate", (3, -1, 0), (4, 1, 0.7))
    scene.camera.location = (-10.0, 0.0, 1.7)
    scene.occ.live = True
    update()
    session = addon("session").SESSION
    r, err = cull()
    envelope = session.shown.envelope if session.shown is not None else None
    floor = getattr(envelope, "floor", None)
    check("floor_found_and_crate_hidden", r == {"FINISHED"} and floor is not None
          and abs(floor[2] - 1.0) < 1e-6 and bpy.data.objects["crate"].occ_culled, (r, envelope, err[-300:]))
    promise("floor_truth")
    centre = session.shown.camera
    scene.camera.location.z = 0.3
    update()
    low, _ = addon("cameras").scene_camera(bpy.context)
    check("floor_lowered_view_leaves_the_envelope", floor is not None and not envelope.holds(centre, low),
          (envelope, low.eye))
    r, err = cull()
    promise("floor_lowered_view_truth")
    scene.occ.live = False
