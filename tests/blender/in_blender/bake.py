"""Baked shots (occ_addon/bake.py): Bake Shot, then Use Baked Shot through play, scrub,
jumps, sub-frames, renames, a save and reload, edits after the bake; every frame
checked against the object-ID truth of the scene camera at that (sub-)frame."""

import os
import random

import bpy
import numpy as np

from .common import WORK, addon, box, check, hidden_but_seen, keyframes, new_scene, update


def _shot(seed: int):
    """The wall of ``new_scene``, seeded boxes behind it, past its ends and small ones
    where its ends sweep across the view, the camera walking along it (frames 1-12),
    turning a little."""
    scene = new_scene()
    rng = random.Random(seed)
    for i in range(14):
        y = rng.uniform(-11, 11)
        x = rng.uniform(2, 8)
        s = rng.uniform(0.3, 1.2)
        box(f"b{i}", (x, y - s, 0), (x + s, y + s, rng.uniform(0.5, 3.0)))
    for i in range(24):                    # small ones where the wall's ends sweep across the view
        y = rng.choice((-1, 1)) * rng.uniform(4.5, 11.0)
        x = rng.uniform(1.0, 6.0)
        s = rng.uniform(0.08, 0.25)
        box(f"e{i}", (x, y - s, 0.5), (x + s, y + s, 0.5 + 2 * s))
    cam = bpy.data.objects["cam"]
    keyframes(cam, [(1, (-10.0, -7.0 + rng.uniform(-1, 1), 1.0)), (12, (-9.0, 7.0 + rng.uniform(-1, 1), 1.5))])
    cam.rotation_euler[2] = -1.5708
    cam.keyframe_insert("rotation_euler", frame=1)
    cam.rotation_euler[2] = -1.5708 + rng.uniform(-0.1, 0.1)
    cam.keyframe_insert("rotation_euler", frame=12)
    scene.frame_start, scene.frame_end = 1, 12
    scene.frame_set(1)
    update()
    return scene


def _expected(scene, f):
    """The names the scene's bake hides at frame ``f`` (its numbers decoded)."""
    b = addon("bake")
    hide = b.frame_mask(b.stored(scene).frame(f), b.numbers())
    return {o.name for o, h in zip(bpy.data.objects, hide, strict=True) if h}


def _hidden():
    return {o.name for o in bpy.data.objects if o.occ_culled or o.occ_view_culled}


def _frames_hold(scene, order, name):
    """At every frame of ``order`` (and half a frame on), the baked set is what is
    hidden and nothing hidden is seen."""
    wrong, seen, total = [], [], 0
    for f in order:
        scene.frame_set(f)
        update()
        got, want = _hidden(), _expected(scene, f)
        total += len(got)
        if got != want:
            wrong.append((f, sorted(got ^ want)))
        bad = hidden_but_seen()
        if bad:
            seen.append((f, bad))
        if f < scene.frame_end:
            scene.frame_set(f, subframe=0.5)       # the set holds for the whole frame
            update()
            bad = hidden_but_seen()
            if bad:
                seen.append((f + 0.5, bad))
    check(f"{name}_is_the_frames_set", not wrong and total > 0, (wrong, total))
    check(f"{name}_truth", not seen, seen)


def baked_shot_workflow():
    """Bake, play forward, backward, jump; rename; save and reload; edits after the bake."""
    scene = _shot(11)
    r = bpy.ops.occ.bake_shot()
    b = scene.occ_bake
    rows = [_expected(scene, f) for f in range(1, 13)]
    check("bake_stored", r == {"FINISHED"} and b.hidden and any(rows) and len({frozenset(x) for x in rows}) > 1,
          (r, [sorted(x) for x in rows]))
    bpy.ops.occ.bake_use()
    _frames_hold(scene, list(range(1, 13)), "bake_play")
    order = list(range(12, 0, -1)) + random.Random(5).sample(range(1, 13), 12)
    _frames_hold(scene, order, "bake_scrub")

    # a rename keeps the object's number
    f = max(range(1, 13), key=lambda k: len(rows[k - 1]))
    victim = sorted(rows[f - 1])[0]
    bpy.data.objects[victim].name = victim + "_renamed"
    scene.frame_set(f)
    update()
    check("bake_survives_rename", bpy.data.objects[victim + "_renamed"].hide_viewport
          and addon("bake").STATE.stale is None, (victim, _hidden()))

    # saved and opened again: the bake and the numbers come back, and hide again
    path = os.path.join(WORK, "baked_shot.blend")
    before = _hidden()
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    check("bake_saved_file_opens_shown", not _hidden(), _hidden())
    scene.frame_set(f)
    update()
    check("bake_survives_reload", scene.occ_bake.use and _hidden() == before and before, (before, _hidden()))
    _frames_hold(scene, [3, 9, 1, 12], "bake_reloaded")

    # edits after the bake: each makes it stale, and a stale bake hides nothing
    edits = [("move", lambda: _move(bpy.data.objects["wall"], 3.0)),
             ("hide", lambda: bpy.data.objects["wall"].hide_set(True)),
             ("delete", lambda: bpy.data.objects.remove(bpy.data.objects["wall"])),
             ("camera", lambda: _move_camera_key(scene)),
             ("hide_while_off", _hide_while_off)]
    for name, edit in edits:
        bpy.ops.wm.open_mainfile(filepath=path)
        scene = bpy.context.scene
        scene.frame_set(f)
        update()
        hid = _hidden()
        edit()
        update()
        scene.frame_set(f)
        update()
        check(f"bake_stale_after_{name}_hides_nothing", hid and not _hidden(), (hid, _hidden()))
        check(f"bake_stale_after_{name}_truth", not hidden_but_seen(), hidden_but_seen())

    # a hidden object made active (an outliner click, a script): shown at once, and not
    # hidden again while it stays so (Blender draws its origin through what is before it)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    scene.frame_set(f)
    update()
    hid = sorted(_hidden())
    bpy.context.view_layer.objects.active = bpy.data.objects[hid[0]]
    update()
    shown_at_once = hid[0] not in _hidden()
    scene.frame_set(f)
    update()
    check("bake_active_never_hidden", hid and shown_at_once and hid[0] not in _hidden()
          and set(_hidden()) == set(hid[1:]), (hid, _hidden(), shown_at_once))

    # a duplicate made after the bake shares its original's number: neither is hidden
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    scene.frame_set(f)
    update()
    hid = sorted(_hidden())
    dup = bpy.data.objects[hid[0]].copy()
    scene.collection.objects.link(dup)
    update()
    scene.frame_set(f)
    update()
    check("bake_duplicate_never_hidden", hid and hid[0] not in _hidden() and dup.name not in _hidden(),
          (hid, _hidden()))
    check("bake_duplicate_truth", not hidden_but_seen(), hidden_but_seen())

    # Use off: everything the bake hid is shown
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    scene.frame_set(f)
    update()
    had = _hidden()
    bpy.ops.occ.bake_use()
    update()
    check("bake_use_off_shows_all", had and not _hidden() and not scene.occ_bake.use, (had, _hidden()))


def _hide_while_off():
    """Use Baked Shot off, the wall hidden (eye), Use on again: the bake must notice."""
    bpy.ops.occ.bake_use()
    bpy.data.objects["wall"].hide_set(True)
    update()
    bpy.ops.occ.bake_use()


def _move(obj, dy):
    obj.location.y += dy


def _move_camera_key(scene):
    """Key the camera elsewhere at the current frame (an animation edit)."""
    cam = scene.camera
    cam.location.y += 2.0
    cam.keyframe_insert("location", frame=scene.frame_current)


def bake_storage_roundtrip():
    """The per-frame bitsets decode to exactly what was encoded (random rows, widths not
    a multiple of 8, one frame, empty rows)."""
    b = addon("bake")
    rng = np.random.default_rng(3)
    ok = []
    for frames, width in ((1, 1), (5, 13), (40, 1000), (3, 8)):
        rows = rng.random((frames, width)) < rng.random()
        ok.append(np.array_equal(b.decode_frames(b.encode_frames(rows), frames, width), rows))
    check("bake_storage_roundtrip", all(ok), ok)


SEEDS = (21, 22, 23)
STEPS = 30


def _step(scene, rng, path):
    """One random user action on a baked shot; returns its description."""
    objs = [o for o in bpy.data.objects if o.type == "MESH"]
    kind = rng.choice(("play", "play", "jump", "sub", "rename", "move", "hide", "duplicate", "rebake",
                       "undo", "save_reload", "use"))
    f = scene.frame_current
    if kind == "play":
        scene.frame_set(min(max(f + rng.choice((1, -1)), scene.frame_start), scene.frame_end))
    elif kind == "jump":
        scene.frame_set(rng.randint(scene.frame_start, scene.frame_end))
    elif kind == "sub":
        scene.frame_set(min(f, scene.frame_end - 1), subframe=rng.choice((0.25, 0.5, 0.75)))
    elif kind == "rename":
        o = rng.choice(objs)
        o.name = f"r{rng.randint(0, 999)}_{o.name}"[:60]
    elif kind == "move":
        rng.choice(objs).location.y += rng.uniform(-2, 2)
    elif kind == "hide":
        o = rng.choice(objs)
        o.hide_set(not o.hide_get())
    elif kind == "duplicate":
        c = rng.choice(objs).copy()
        scene.collection.objects.link(c)
    elif kind == "rebake":
        bpy.ops.occ.bake_shot()
    elif kind == "undo":
        if bpy.ops.ed.undo.poll():            # (a file just opened has nothing to undo)
            bpy.ops.ed.undo()
        scene = bpy.context.scene
    elif kind == "save_reload":
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        scene = bpy.context.scene
        bpy.ops.ed.undo_push(message="opened")
    elif kind == "use":
        bpy.ops.occ.bake_use()
    if kind not in ("undo", "save_reload", "rebake", "use", "play", "jump", "sub"):
        bpy.ops.ed.undo_push(message=kind)
    update()
    return kind, bpy.context.scene


def seeded_bake_workflows():
    """Seeded sequences of play, jumps, sub-frames, renames, moves, hides, duplicates,
    bakes again, undo, save and reload, Use switched: after every step nothing hidden is
    seen (the truth at that (sub-)frame), and what is hidden is the frame's baked set
    exactly while the bake holds, else nothing."""
    b = addon("bake")
    seen, wrong, checked, hidden_at = [], [], 0, 0
    for seed in SEEDS:
        rng = random.Random(seed)
        scene = _shot(seed)
        bpy.ops.ed.undo_push(message="shot")
        bpy.ops.occ.bake_shot()
        bpy.ops.occ.bake_use()
        path = os.path.join(WORK, f"bake_seed_{seed}.blend")
        for step in range(STEPS):
            kind, scene = _step(scene, rng, path)
            got = _hidden()
            bad = hidden_but_seen()
            if bad:
                seen.append((seed, step, kind, bad))
            st = b.STATE
            if scene.occ_bake.use and scene.frame_current_final == scene.frame_current and st.owns():
                want = _expected(scene, scene.frame_current) if st.stale is None else set()
                if got != want:
                    wrong.append((seed, step, kind, sorted(got ^ want)))
            elif st.known and st.stale is not None and got:
                wrong.append((seed, step, kind, "stale but hides", sorted(got)))
            checked += 1
            hidden_at += len(got)
    check("bake_seeded_truth", not seen and checked == len(SEEDS) * STEPS, seen)
    check("bake_seeded_sets", not wrong, wrong)
    check("bake_seeded_had_teeth", hidden_at >= 20, hidden_at)


def render_baked_shot():
    """Render Baked Shot writes every frame where ``blender -a`` would, each with its set
    hidden from the render, pixel for pixel the frame rendered whole (Workbench), and
    leaves every ``hide_render`` as it was (one the user set stays); a stale bake renders
    nothing and says why."""
    scene = _shot(11)
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.join(WORK, "shot", "f_")
    bpy.data.objects["b3"].hide_render = True             # the user's own (hidden in the viewport too:
    bpy.data.objects["b3"].hide_set(True)                 # else the bake culls against it, which renders not)
    bpy.ops.occ.bake_shot(frame_start=1, frame_end=4)
    r = bpy.ops.occ.render_baked()
    from .policy import _render
    same, hidden = [], []
    paths = {f: scene.render.frame_path(frame=f) for f in range(1, 5)}    # (_render moves the output path)
    for f, path in paths.items():
        if not os.path.exists(path):
            same.append((f, "missing"))
            continue
        img = bpy.data.images.load(path, check_existing=False)
        got = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], img.channels)
        bpy.data.images.remove(img)
        scene.frame_set(f)
        whole = _render(os.path.join(WORK, f"shot_whole_{f}.png"))
        same.append((f, int((np.abs(got - whole) > 1.0 / 255.0).any(axis=2).sum())))
        hidden.append(len(_expected(scene, f)))
    flags = sorted(o.name for o in bpy.data.objects if o.hide_render)
    check("render_baked_frames_pixel_identical", r == {"FINISHED"} and all(n == 0 for _, n in same)
          and sum(hidden) > 0, (r, same, hidden))
    check("render_baked_hide_render_as_it_was", flags == ["b3"], flags)
    _move(bpy.data.objects["wall"], 3.0)
    update()
    try:
        bpy.ops.occ.render_baked()
        refused = ""
    except RuntimeError as e:                           # the operator's ERROR report
        refused = str(e)
    check("render_baked_stale_refused", "stale" in refused, refused)


def _refusal(op):
    """The operator's refusal (its ERROR report), or "" where it went ahead."""
    try:
        op()
    except RuntimeError as e:
        return str(e)
    return ""


def render_geometry_refused():
    """A bake reads the viewport's geometry: a wall subdivided only in the render (levels 0
    in the viewport, 3 in the render: a pillow, smaller) uncovers a crate the bake hid
    behind its corner (Workbench's render says so).  Render Baked Shot and Apply to Render
    refuse, naming the wall's modifier; with the levels the same both go ahead."""
    from .policy import _changed, _crate_renders
    scene = new_scene()
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.color_type = "OBJECT"
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.join(WORK, "pillow", "f_")
    scene.frame_start = scene.frame_end = 1
    wall = bpy.data.objects["wall"]
    wall.location, wall.scale = (0.25, 0.0, 1.0), (0.5, 3.0, 3.0)          # x 0..0.5, y and z 3 wide
    crate = box("crate", (3.0, 1.2, 2.0), (3.5, 1.7, 2.6))                # behind the wall's corner
    crate.color = (1.0, 0.0, 0.0, 1.0)
    sub = wall.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 0, 3
    update()
    seen = _changed(*_crate_renders("pillow"))
    bpy.ops.occ.bake_shot(frame_start=1, frame_end=1)
    baked = "crate" in _expected(scene, 1)
    refused = (_refusal(bpy.ops.occ.render_baked), _refusal(bpy.ops.occ.bake_render))
    sub.levels = 3
    update()
    bpy.ops.occ.bake_shot(frame_start=1, frame_end=1)
    same = (_refusal(bpy.ops.occ.render_baked), _refusal(bpy.ops.occ.bake_render))
    bpy.ops.occ.bake_render()                                                # off again
    check("render_geometry_refused", seen > 0 and baked and all("'wall'" in r and "Subdivision" in r for r in refused)
          and same == ("", ""), (seen, baked, refused, same))


def baked_frames_render_unchanged():
    """A baked frame's set hidden from Blender's own render (``hide_render``, as a final
    render would take it) changes no pixel beyond the renderer's own run-to-run noise,
    EEVEE (one sample) and Workbench with shadows and without, on the lit-render scene with its
    camera animated (casters seen only through their shadows, an emissive and a mirror
    box and two crates behind a wall); and the check can fail: hiding the slab that shadows the view
    changes pixels."""
    from .policy import _lit_scene, _render
    try:
        bpy.context.scene.render.engine = eevee = "BLENDER_EEVEE"
    except TypeError:                                   # Blender 4.2-4.4's name for it
        eevee = "BLENDER_EEVEE_NEXT"
    for engine, tag, shadows in ((eevee, "eevee", True), ("BLENDER_WORKBENCH", "workbench", True),
                                 ("BLENDER_WORKBENCH", "workbench_flat", False)):
        scene = _lit_scene()
        scene.render.engine = engine
        scene.display.shading.show_shadows = shadows
        if engine == eevee:
            scene.eevee.taa_render_samples = 1
        for name, lo, hi in (("crate_a", (7.5, -3.0, 0.0), (8.3, -2.2, 0.8)),
                             ("crate_b", (7.2, 1.5, 0.0), (7.8, 2.1, 1.5))):
            box(name, lo, hi)                  # behind the wall, inside the frame: what a bake hides
        cam = scene.camera
        keyframes(cam, [(1, (-10.0, -1.5, 3.0)), (4, (-9.0, 1.5, 3.2))])
        scene.frame_start, scene.frame_end = 1, 4
        r = bpy.ops.occ.bake_shot()
        changed, noise, hid = [], 0.0, []
        for f in (1, 3):
            scene.frame_set(f)
            update()
            a = _render(os.path.join(WORK, f"bake_{tag}_{f}_a.png"))
            b = _render(os.path.join(WORK, f"bake_{tag}_{f}_b.png"))
            noise = max(noise, float(np.abs(a - b).max()))
            want = _expected(scene, f)
            hid.append(sorted(want))
            for o in bpy.data.objects:
                o.hide_render = o.name in want
            c = _render(os.path.join(WORK, f"bake_{tag}_{f}_c.png"))
            changed.append(int((np.abs(c - a) > noise + 1.0 / 255.0).any(axis=2).sum()))
            for o in bpy.data.objects:
                o.hide_render = o.name == "slab"
            d = _render(os.path.join(WORK, f"bake_{tag}_{f}_d.png"))
            for o in bpy.data.objects:
                o.hide_render = False
            changed.append(-int((np.abs(d - a) > noise + 1.0 / 255.0).any(axis=2).sum()))
        # (Workbench's shadows sweep every crate's shadow past the wall's end: it hides nothing there)
        check(f"bake_render_{tag}_no_pixel_changed", r == {"FINISHED"} and all(c == 0 for c in changed[0::2])
              and (any(hid) or tag == "workbench"), (r, hid, changed, noise))
        if shadows:
            check(f"bake_render_{tag}_slab_shadow_shows", all(c < 0 for c in changed[1::2]), (changed, noise))
    _cycles_bake()


def _cycles_bake():
    """Cycles traces rays: a bake hides nothing there unless the user opts in (Cull Under Ray
    Tracing).  With the opt-in it hides the crates behind the wall, and what that changes in
    Cycles' pixels (indirect light, the mirror box) is what the opt-in accepts: counted, not
    required to be none."""
    from .policy import _lit_scene, _render
    hid, changed = {}, {}
    for opt_in in (False, True):
        scene = _lit_scene()
        scene.render.engine = "CYCLES"
        scene.cycles.samples, scene.cycles.seed, scene.cycles.use_denoising = 4, 1, False
        scene.occ.cull_raytraced = opt_in
        for name, lo, hi in (("crate_a", (7.5, -3.0, 0.0), (8.3, -2.2, 0.8)),
                             ("crate_b", (7.2, 1.5, 0.0), (7.8, 2.1, 1.5))):
            box(name, lo, hi)
        keyframes(scene.camera, [(1, (-10.0, -1.5, 3.0)), (4, (-9.0, 1.5, 3.2))])
        scene.frame_start, scene.frame_end = 1, 4
        r = bpy.ops.occ.bake_shot()
        hid[opt_in] = [sorted(_expected(scene, f)) for f in range(1, 5)] if r == {"FINISHED"} else r
        if opt_in and r == {"FINISHED"}:
            scene.frame_set(1)
            update()
            a = _render(os.path.join(WORK, "bake_cycles_a.png"))
            for o in bpy.data.objects:
                o.hide_render = o.name in hid[True][0]
            c = _render(os.path.join(WORK, "bake_cycles_c.png"))
            for o in bpy.data.objects:
                o.hide_render = False
            changed[opt_in] = int((np.abs(c - a) > 1.0 / 255.0).any(axis=2).sum())
    check("bake_render_cycles_hides_nothing", hid[False] == [[]] * 4, hid)
    check("bake_render_cycles_opt_in_hides", isinstance(hid[True], list) and any(hid[True]), (hid, changed))


def _render_hidden():
    """Names hidden from the render at the evaluated frame (the keys' values as evaluated)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return {o.name for o in bpy.data.objects if o.evaluated_get(depsgraph).hide_render}


def _keys_hold(scene, frames, name, own=frozenset()):
    """At every frame (and half a frame on) the render hides the frame's baked set and the
    user's own hides, before and after the bake's range the user's alone."""
    b = addon("bake")
    baked = b.stored(scene)
    wrong = []
    for f in frames:
        for sub in (0.0, 0.5):
            scene.frame_set(f, subframe=sub)
            want = set(own) | (_expected(scene, f) if baked.start <= f <= baked.end else set())
            got = _render_hidden()
            if got != want:
                wrong.append((f + sub, sorted(got ^ want)))
    check(name, not wrong, wrong)


def _render_keyed():
    """Names of the objects carrying the add-on's render keys."""
    return sorted(o.name for o in addon("render_keys").keyed_objects())


def _glass(obj):
    """Give ``obj`` a glass material (what is behind it shows)."""
    mat = bpy.data.materials.new("glass")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    mat.node_tree.links.new(nodes.new("ShaderNodeBsdfGlass").outputs[0], nodes.get("Material Output").inputs["Surface"])
    obj.data.materials.append(mat)


def _unreported_edits_remove_keys(path):
    """Edits Blender reports to no handler of the keyed scene (the add-on's settings: no
    update callbacks; an object moved while another scene that holds it is shown) leave
    the keys standing until the window's poll, a render in background mode or a save
    checks them: each removes them (the edit alone did not: else this checks nothing)."""
    def exclude():
        scene = bpy.context.scene
        scene.occ.exclude_collection = scene.collection.children[0] if len(scene.collection.children) \
            else bpy.data.collections.new("kept")

    out_path = os.path.join(WORK, "render_keys_saved.blend")
    ways = {"poll": lambda: addon("render_keys").poll(),
            "render": lambda: bpy.ops.render.render(),
            "save": lambda: bpy.ops.wm.save_as_mainfile(filepath=out_path, copy=True)}
    def moved_from_another_scene():
        """The wall, linked into a second scene too, moved while the window shows that
        scene: the edit's handler call is the second scene's."""
        first, win = bpy.context.scene, bpy.context.window
        other = bpy.data.scenes.new("other")
        other.collection.objects.link(first.objects["wall"])
        win.scene = other
        update()
        other.objects["wall"].location.z += 0.5
        update()
        win.scene = first
        update()

    edits = {"cull_raytraced": lambda: setattr(bpy.context.scene.occ, "cull_raytraced", True),
             "moved_from_another_scene": moved_from_another_scene,
             "exclude_collection": exclude,
             "exclude_children": lambda: setattr(bpy.context.scene.occ, "exclude_children",
                                                 not bpy.context.scene.occ.exclude_children)}
    got = {}
    for name, edit in edits.items():
        for way, run in ways.items():
            bpy.ops.wm.open_mainfile(filepath=path)
            scene = bpy.context.scene
            scene.frame_set(4)
            edit()
            update()
            stood = bool(scene.occ_bake.render_keys and _render_keyed())
            run()
            got[f"{name}_{way}"] = (stood, bool(scene.occ_bake.render_keys), _render_keyed(),
                                    sorted(_render_hidden()), scene.occ_bake.render_note[:60])
    check("render_keys_removed_after_unreported_edits",
          all(stood and not keys and not left and hidden == ["b3"] for stood, keys, left, hidden, _ in got.values()),
          got)


def render_keys_workflow():
    """Apply to Render: keys of hide_render that hold the baked sets at every frame and
    sub-frame (and nothing outside the range); Render Animation (what blender -a runs)
    renders every frame pixel for pixel as the whole scene; the keyed objects stay
    static for the add-on; the keys survive a save and reload; an edit, a camera key, a
    key the user adds, a clear or a new bake removes them (the user's own keys stay);
    a camera that is driven, and a scene rendering other view layers, are refused."""
    scene = _shot(11)
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.render.image_settings.file_format = "PNG"
    bpy.data.objects["b3"].hide_render = True             # the user's own (hidden in the viewport too:
    bpy.data.objects["b3"].hide_set(True)                 # else the bake culls against it, which renders not)
    bpy.ops.occ.bake_shot(frame_start=2, frame_end=9)
    from .policy import _render
    whole = {}
    for f in (2, 5, 9):
        scene.frame_set(f)
        whole[f] = _render(os.path.join(WORK, f"keys_whole_{f}.png"))
    r = bpy.ops.occ.bake_render()
    b = scene.occ_bake
    keyed = _render_keyed()
    check("render_keys_written", r == {"FINISHED"} and b.render_keys and keyed and "b3" not in keyed, (r, keyed))
    _keys_hold(scene, range(0, 12), "render_keys_are_the_frames_sets", {"b3"})
    kinds = addon("kinds")
    check("render_keys_objects_static", not any(kinds.is_dynamic(bpy.data.objects[n]) for n in keyed), keyed)
    scene.render.filepath = os.path.join(WORK, "keys_anim", "f_")
    scene.frame_start, scene.frame_end = 2, 9
    scene.frame_step = 1
    bpy.ops.render.render(animation=True)
    changed, hid = [], 0
    for f in (2, 5, 9):
        img = bpy.data.images.load(scene.render.frame_path(frame=f), check_existing=False)
        got = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], img.channels)
        bpy.data.images.remove(img)
        changed.append(int((np.abs(got - whole[f]) > 1.0 / 255.0).any(axis=2).sum()))
        hid += len(_expected(scene, f))
    check("render_keys_animation_pixel_identical", all(c == 0 for c in changed) and hid > 0, (changed, hid))

    path = os.path.join(WORK, "render_keys.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    check("render_keys_survive_reload", scene.occ_bake.render_keys and _render_keyed() == keyed,
          (_render_keyed(), scene.occ_bake.render_note))
    _keys_hold(scene, (1, 4, 9, 10), "render_keys_reloaded_sets", {"b3"})

    def user_key():
        o = bpy.data.objects[keyed[0]]
        o.keyframe_insert("location", frame=3)         # into the add-on's action: the user's now
    edits = [("move", lambda: _move(bpy.data.objects["wall"], 3.0)),
             ("camera", lambda: _move_camera_key(scene)),
             ("users_key", user_key),
             ("engine", lambda: setattr(scene.render, "engine", "CYCLES")),
             ("wall_render_hidden", lambda: setattr(bpy.data.objects["wall"], "hide_render", True)),
             ("wall_no_camera_rays", lambda: setattr(bpy.data.objects["wall"], "visible_camera", False)),
             ("wall_made_glass", lambda: _glass(bpy.data.objects["wall"])),
             ("never_cull", lambda: setattr(bpy.data.objects[keyed[0]], "occ_never_cull", True)),
             ("linked_into_another_scene", lambda: bpy.data.scenes.new("other").collection.objects.link(
                 bpy.data.objects[keyed[0]])),
             ("clear", lambda: bpy.ops.occ.bake_clear()),
             ("rebake", lambda: bpy.ops.occ.bake_shot(frame_start=2, frame_end=9))]
    for name, edit in edits:
        bpy.ops.wm.open_mainfile(filepath=path)
        scene = bpy.context.scene
        scene.frame_set(4)
        edit()
        update()
        scene.frame_set(5)
        left = _render_keyed()
        flags = sorted(_render_hidden())
        marked = [a.name for a in bpy.data.actions if a.get("occ_render_keys") is not None]
        own = ["b3", "wall"] if name == "wall_render_hidden" else ["b3"]
        check(f"render_keys_removed_after_{name}", not scene.occ_bake.render_keys and not left and not marked
              and flags == own, (left, flags, marked, scene.occ_bake.render_note))
    o = bpy.data.objects[keyed[0]]
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    user_key()
    update()
    o = bpy.data.objects[keyed[0]]
    ad = o.animation_data
    curves = addon("kinds").action_curves(ad.action, getattr(ad, "action_slot", None)) if ad and ad.action else []
    check("render_keys_keep_users_keys", sorted({c.data_path for c in curves}) == ["location"],
          [c.data_path for c in curves])

    _unreported_edits_remove_keys(path)

    refusals = {}
    for name, setup in (("constraint", lambda: bpy.context.scene.camera.constraints.new("TRACK_TO")),
                        ("layers", lambda: bpy.context.scene.view_layers.new("other"))):
        bpy.ops.wm.open_mainfile(filepath=path)
        bpy.ops.occ.bake_render()                        # off (the file had them on)
        bpy.ops.occ.bake_shot(frame_start=2, frame_end=9)
        setup()
        update()
        try:
            got = bpy.ops.occ.bake_render()
        except RuntimeError as e:                        # the operator's ERROR report
            got = str(e)
        refusals[name] = (str(got), _render_keyed())
    check("render_keys_refused", all("Apply to Render" in g and not k for g, k in refusals.values()), refusals)
