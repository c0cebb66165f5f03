"""Seeded random user workflows in real Blender (bpy) against the installed add-on
(issue 9, "How it is checked").  Runs in its own process; prints one JSON line
``OCC_WORKFLOWS {...}``.

Each seed builds a small scene (walls, props, two view layers and the features
of ``FEATURES``: instancers of every kind, animation, drivers, constraints,
modifiers, shape keys, curves) and runs ``--steps`` steps drawn from ``KINDS``
(what users do).  After every step:

(a) after a cull, and after every step while live mode is on: no object that
    covers a pixel of an object-ID render of the scene as Blender would draw it
    if the add-on had hidden nothing (from the scene camera, at the render
    resolution) is hidden by the add-on;
(b) every hide flag, collection flag and add-on setting the user set is as set
    (the generator keeps its own model of what the user did), and every object
    the add-on did not hide is visible exactly when the user's flags say so
    (``visible_get``: catches a flag that reads "shown" while Blender never draws);
(c) after Restore (and with the add-on disabled) nothing is hidden by the add-on;
(d) no exception escaped and nothing printed a traceback;
(e) after a cull, "never cull" objects, the exclude collection and objects with a
    NaN are not hidden;
(f) live mode shows on exactly when its timer runs;
(g) a NaN in one object never stops a cull;
(h) around every operation of the add-on (cull, restore, a live pass, analyze with
    or without "Collect Never Visible", enabling and disabling it): no object that
    was in a collection is in none after it (or has no users), and no object leaves
    ``bpy.data.objects``;
and an analyze step's report names, per frame, every object the truth sees.

Some steps carry the ingredients of a known crash of Blender itself (README Limits;
../shared/repro/blender_hair_undo_two_layers.py): view layers added, removed and
shown, a second scene shown, instance sources of hair (object and collection) and
geometry nodes moved, an emitter deleted and the deletion undone (and redone), a
file reverted.  A seed that crashes Blender ends its process (rc -11 / 139); with
``--progress FILE`` each step is written there before it runs, so the crashing step
is known (tests/blender/test_workflows.py and tools/checks/crash_campaign.py read it).

The truth is computed independently of the add-on's extractor: the evaluated
depsgraph's object instances (instances included), their evaluated triangles
and world matrices, into ``core.Scene`` (imported from the repository), drawn
by ``core.Culler.truth``.  An object the add-on hid is not evaluated by Blender,
so it is represented by a temporary copy (the add-on's record cleared, the
user's flags) evaluated in its place, then removed: the add-on's own objects and
records are never touched by the check.

Reproduce one seed:  python tests/blender/workflows.py --seed N [--steps 300]
(builds the extension zip and installs it in a temporary user folder first).
Does a crash need the add-on?  ... --seed N --steps S --plain  (the same step kinds, the
add-on never installed, its steps skipped: each step draws from a generator of its own).
Many seeds, one process each, crashes counted:  python tools/checks/crash_campaign.py --help
"""

import argparse
import contextlib
import copy
import faulthandler
import io
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
EXT_ID = "occlusion_culled_viewport"
ADDON_MODULE = f"bl_ext.user_default.{EXT_ID}"
RESOLUTION = (160, 90)
FRAMES = (1, 60)
HISTORY_TAIL = 25
# --ground HALF: a ground slab HALF wide each way under the scene (its top at -0.5, where
# the walls stand): live mode's rest envelope (0.6 % of the scene's size) then reaches
# under it from low cameras, and its passes keep their eyes above a floor
GROUND = {"half": 0.0}

# Step kinds and their weights: what users do, in rough proportion.
KINDS = {
    "cull": 14, "restore": 4, "camera_move": 8, "camera_scale": 3, "camera_lens": 2,
    "object_move": 8, "hide_eye": 5, "hide_monitor": 5, "coll_eye": 2, "coll_exclude": 2,
    "coll_monitor": 2, "view_layer": 4, "add": 3, "delete": 2, "rename": 2, "rename_swap": 1,
    "rename_replace": 1, "duplicate": 2, "link": 2, "move_collection": 2, "frame": 4,
    "never_cull": 2, "exclude_setting": 2, "undo": 3, "redo": 3, "save_reload": 1,
    "addon_toggle": 1, "live": 2, "analyze": 3, "display_type": 2, "bad_value": 1,
    "mesh_edit": 3, "object_scale": 2, "settings": 2, "camera_nudge": 4,
    # the ingredients of a known crash of Blender itself (issue 30; README Limits), each
    # weighted to come up several times in every 300-step seed
    "instance_move": 5, "scene_switch": 4, "emitter_undo": 4, "revert": 3,
    # what a user does with the "Never Visible" collection an analysis collected
    "nv_move": 3, "nv_add": 3, "nv_duplicate": 3,
}
# A baked shot: baked, switched on and off, played forward, backward and between frames.
# Drawn from a generator of their own, each standing in for a step of KINDS this often:
# the kinds of every other step stay those of the seed before baked shots existed (the
# seeds that found a bug or a crash replay the same sequence with --skip of these).
# (Their scenes' cameras see few objects occluded wholly inside the frame, which is all a
# bake hides; the baked frames' truth with many hidden is tests/blender/test_bake.py's.)
BAKE_KINDS = {"bake": 3, "bake_use": 1, "play": 5, "bake_render": 1, "render": 2}
BAKE_SHARE = 0.06
# Scene features, switched off like step kinds: a geometry-nodes instancer whose
# instances stand far from its mesh, props animated by keyframes, props carried by
# an animated parent (an empty) or following it by a constraint, hair particles
# instancing an object, a vertex instancer (a point mesh and its child), props
# with an array modifier, a text and a bevelled curve, a prop moved by a driver and
# one whose animated shape key raises it; a second hair system instancing a collection
# and a geometry-nodes instancer of an object (their sources moved by "instance_move"),
# and a second scene that shares the walls and props ("scene_switch").
FEATURES = {"scene_gn", "scene_animated", "scene_parent", "scene_particles", "scene_verts", "scene_modifiers",
            "scene_curves", "scene_deform", "scene_hair_collection", "scene_gn_object", "scene_second"}
# Instancers whose instances vanish when their source object is hidden (monitor):
# the source counts as seen wherever its instances are.  Particle instances stay
# drawn when their object is hidden; geometry nodes here use no object.
SOURCE_HIDES_INSTANCES = {"VERTS", "FACES", "COLLECTION"}
# Steps that need the add-on enabled (its operators or properties).
NEEDS_ADDON = {"cull", "restore", "never_cull", "exclude_setting", "live", "analyze", "settings", "bake", "bake_use",
               "bake_render", "render"}
# Steps after which Blender's undo system gets a step, as the UI pushes one after
# every user edit (the add-on's Cull and Restore carry no UNDO flag: no push; an
# analysis pushes its own step when it collects the never-visible objects).
NO_PUSH = {"cull", "restore", "undo", "redo", "save_reload", "addon_toggle", "live", "analyze", "emitter_undo",
           "revert", "bake", "bake_use", "play", "render"}
# Steps that run the add-on's own operations, checked by (h) around them (analyze:
# around its operator only; the live pass after every step while live mode is on).
ADDON_OPS = {"cull", "restore", "live", "addon_toggle", "bake", "bake_use", "bake_render"}
# What --plain skips besides NEEDS_ADDON: the add-on's switch.
PLAIN_SKIPS = {"addon_toggle"}
NEVER_VISIBLE = "Never Visible"        # the collection "Collect Never Visible" fills (occ_addon/analysis.py)

# Step kinds switched off because the add-on still fails them, each with its reason.
# Empty when the add-on passes everything.
KNOWN_UNFIXED = {
    "undo_while_disabled": (
        "undo/redo while the add-on is disabled: an undo step pushed while culled holds the add-on's "
        "hide flags (memfile undo restores Blender data as it was), and with the add-on disabled no "
        "code runs to show them again; enabling the add-on restores them (checked: every enable is "
        "followed by the state check).  Not fixable from the add-on while its hiding is Blender data."),
}

# Narrower switches for KNOWN_UNFIXED (a situation, not a whole step kind):
#   "instanced_member_drawn": no member of the instanced collection 'Lib' is also drawn
#       directly (new view layers exclude 'Lib'; a member moved elsewhere leaves 'Lib');
#   "wire_instanced_member": members of 'Lib' keep a solid display;
#   "hair_member_drawn": the same as "instanced_member_drawn" for 'HairLib', the
#       collection a hair system instances (fixed: what a particle system instances is
#       never hidden; the switch stays for a replay of the old behaviour).

# What cannot be exercised in background Blender (said in the report, not silently):
NOT_EXERCISED = {
    "cull_viewport": "background Blender has no 3D viewport: only the scene-camera source is culled",
    "live_operator": "occ.live refuses in background mode and timers never run headless: live mode is "
                     "started and stopped through its module (start / stop, as the operator does) and "
                     "its timer function is called by hand after every step, debounce off",
    "render_keys_poll": "timers never run headless: the render keys' poll of what changes without a "
                        "depsgraph update (the add-on's settings, view layers, markers) is called by hand "
                        "after every step, as the window's timer calls it",
    "leave_timer": "timers never run headless: the timer by which an edit, a new frame or an undo shows the "
                   "hidden set on screen (live.edited, the redraw guard) is called by hand after every "
                   "step, as the window runs it before the next redraw",
    "message_bus": "the message bus is served by the window's event loop: the add-on's callback for a "
                   "window's view-layer switch (localview.on_window_change) is called by hand after one",
}
LIVE_TICKS = 3        # a tick that sees a new view only records it; the next one culls

GEOMETRY = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
# 12 triangles over the corners of a box, corner k = (x, y, z) bits (1, 2, 4) of k
BOX_FACES = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
             [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]


# --------------------------------------------------------------------------- bootstrap

def bootstrap(args):
    """Standalone use: build the zip and re-run this script with an isolated user folder."""
    work = tempfile.mkdtemp(prefix="occ_workflows_")
    dist = os.path.join(work, "dist")
    subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py"), "--no-wheels",
                    "--out", dist], cwd=ROOT, check=True)
    zips = [os.path.join(dist, f) for f in os.listdir(dist) if f.endswith(".zip")]
    # the same string hashes as the test (set order inside the add-on repeats too)
    env = {**os.environ, "BLENDER_USER_RESOURCES": os.path.join(work, "user"), "PYTHONHASHSEED": "0"}
    cmd = [sys.executable, os.path.abspath(__file__), "--zip", zips[0], "--work", work] + sys.argv[1:]
    rc = subprocess.run(cmd, env=env).returncode
    sys.exit(128 - rc if rc < 0 else rc)        # killed by a signal: as a shell says it (139: SIGSEGV)


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--zip", help="extension zip (default: build one and install it in a temporary folder)")
    p.add_argument("--work", help="folder for saved files")
    p.add_argument("--seed", type=int, action="append", help="seed (repeatable)")
    p.add_argument("--seeds", help="comma-separated seeds")
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--skip", default="", help="comma-separated step kinds to leave out")
    p.add_argument("--validate", action="store_true",
                   help="harness self-check: never enable the add-on (every check must pass)")
    p.add_argument("--plain", action="store_true",
                   help="plain Blender: the same step kinds as the seed's run, the add-on never installed and "
                        "its steps skipped (does a crash need the add-on?)")
    p.add_argument("--verbose", action="store_true", help="print each step")
    p.add_argument("--hide-in", default="AUTO", choices=("AUTO", "VIEW", "EVERYWHERE"),
                   help="the add-on's Hide In setting (VIEW: the window's 3D view's local-view bits)")
    p.add_argument("--ground", type=float, default=0.0,
                   help="a ground slab this wide each way under the scene (live mode's envelope finds a floor)")
    p.add_argument("--tail", type=int, default=HISTORY_TAIL, help="history steps shown with a failure")
    p.add_argument("--drop", default="", help="comma-separated step numbers done as nothing (the same "
                   "kinds after them: to narrow down what a crash needs)")
    p.add_argument("--progress", help="file each step is written to before it runs (what a crash leaves)")
    return p.parse_args(argv)


# --------------------------------------------------------------------------- the add-on's record

def addon_enabled():
    import bpy
    return ADDON_MODULE in bpy.context.preferences.addons


# the add-on's "Hide In" setting for every scene (--hide-in): AUTO hides everywhere in
# background mode (hide_viewport), VIEW in the window's 3D view (its local-view bits)
HIDE_IN = {"mode": "AUTO"}


def window_view():
    """The window's 3D view (``SpaceView3D``): no step enters local view, so a local view
    there is the add-on's own."""
    import bpy
    wm = bpy.context.window_manager
    for win in (wm.windows if wm is not None else ()):
        for area in win.screen.areas:
            if area.type == "VIEW_3D":
                return area.spaces.active
    return None


def addon_hidden(obj):
    """Whether the add-on's own records say it hid ``obj`` (the one place that knows the mechanism)."""
    if not addon_enabled():
        return False
    return bool(getattr(obj, "occ_culled", False) or getattr(obj, "occ_view_culled", False))


def hidden_by_addon(obj):
    """The add-on hid ``obj`` and it is hidden now: its monitor icon, or the window's 3D
    view's local-view bit."""
    import bpy
    if not addon_hidden(obj):
        return False
    if obj.occ_culled and obj.hide_viewport:
        return True
    space = window_view()
    layer = bpy.context.view_layer
    # recorded, and the view does not draw what the view layer shows: its bit is clear
    return bool(obj.occ_view_culled) and space is not None and space.local_view is not None \
        and layer.objects.get(obj.name) is not None and obj.visible_get(view_layer=layer) \
        and not obj.visible_get(view_layer=layer, viewport=space)


def clear_addon_record(obj):
    """Make a copy plain: no record of the add-on's hiding."""
    for prop in ("occ_culled", "occ_view_culled"):
        if hasattr(obj, prop):
            setattr(obj, prop, False)


# --------------------------------------------------------------------------- scene

class World:
    """The running state of one seed: rng, model of the user's intent, undo mirror, history."""

    def __init__(self, seed, work, validate, skip, plain=False):
        self.seed = seed
        self.rng = random.Random(seed)          # the scene's build; then each step's own (run_seed)
        self.choices = random.Random(seed)      # the sequence of step kinds
        self.bake_choices = random.Random(f"{seed}:bake")   # where a baked-shot step stands in, and which
        self.bake_kinds = {k: w for k, w in BAKE_KINDS.items() if k not in skip and not validate}
        self.work = work
        self.validate = validate
        self.plain = plain          # the same sequence without the add-on: its steps skipped
        self.plain_on = True        # plain: whether the add-on would be enabled now
        self.kinds = {k: w for k, w in {**KINDS, **dict.fromkeys(FEATURES, 0)}.items()
                      if k not in skip and k not in KNOWN_UNFIXED}
        if validate:
            for k in NEEDS_ADDON | {"addon_toggle"}:
                self.kinds.pop(k, None)
        self.next_id = 1
        self.model = None
        self.undo = []              # model snapshots, one per Blender undo step
        self.undo_pos = -1
        self.history = []
        self.counts = {}
        self.stats = {"truth_checks": 0, "hidden_at_checks": 0, "visible_at_checks": 0, "bake_checks": 0,
                      "render_checks": 0, "floor_checks": 0}
        self.pending = []           # problems a step found itself (analyze)
        self.saved = None           # (path, model) of the file saved last
        self.note = ""              # what a step did before its own action (a first analysis)
        self.drop = set()           # step numbers done as nothing (--drop)


def new_id(w, obj):
    obj["wf_id"] = w.next_id
    w.next_id += 1
    return obj["wf_id"]


def box_mesh(name):
    import bmesh
    import bpy
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bm.to_mesh(mesh)
    bm.free()
    return mesh


def add_box(w, name, loc, size, coll, rot_z=0.0):
    import bpy
    obj = bpy.data.objects.new(name, box_mesh(name))
    coll.objects.link(obj)
    obj.location = loc
    obj.scale = size
    obj.rotation_euler = (0.0, 0.0, rot_z)
    new_id(w, obj)
    return obj


def scatter_group():
    """A geometry-nodes group: the input mesh plus cubes instanced on a line far from it."""
    import bpy
    ng = bpy.data.node_groups.new("wf_scatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    line = ng.nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = 3
    line.inputs["Start Location"].default_value = (-7.0, -3.0, 0.5)
    line.inputs["Offset"].default_value = (0.0, 3.0, 0.0)
    cube = ng.nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (0.7, 0.7, 0.7)
    iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
    join = ng.nodes.new("GeometryNodeJoinGeometry")
    ng.links.new(line.outputs["Mesh"], iop.inputs["Points"])
    ng.links.new(cube.outputs["Mesh"], iop.inputs["Instance"])
    ng.links.new(gin.outputs[0], join.inputs[0])
    ng.links.new(iop.outputs["Instances"], join.inputs[0])
    ng.links.new(join.outputs[0], gout.inputs[0])
    return ng


def object_scatter_group(src):
    """A geometry-nodes group: the input mesh plus three instances of object ``src``
    (its transform relative to the modified object: moving ``src`` moves them)."""
    import bpy
    ng = bpy.data.node_groups.new("wf_objscatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    line = ng.nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = 3
    line.inputs["Offset"].default_value = (1.5, 1.0, 0.0)
    info = ng.nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = src
    info.inputs["As Instance"].default_value = True
    info.transform_space = "RELATIVE"
    iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
    join = ng.nodes.new("GeometryNodeJoinGeometry")
    ng.links.new(line.outputs["Mesh"], iop.inputs["Points"])
    ng.links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    ng.links.new(gin.outputs[0], join.inputs[0])
    ng.links.new(iop.outputs["Instances"], join.inputs[0])
    ng.links.new(join.outputs[0], gout.inputs[0])
    return ng


def build_scene(w):
    import bpy
    rng = w.rng
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = *RESOLUTION, 100
    scene.frame_start, scene.frame_end = FRAMES
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    colls = {}
    for name, parent in (("Walls", None), ("Props", None), ("Sub", "Props"), ("Moving", None)):
        c = bpy.data.collections.new(name)
        (colls[parent] if parent else scene.collection).children.link(c)
        colls[name] = c
    for i in range(6):                                   # walls: the occluders
        length, height = rng.uniform(5, 11), rng.uniform(2, 4.5)
        add_box(w, f"Wall.{i:03d}" if i else "Wall", (rng.uniform(-5, 5), rng.uniform(-5, 5), height / 2 - 0.5),
                (0.3, length, height), colls["Walls"], rng.uniform(0, math.pi))
    if GROUND["half"] > 0.0:                             # a ground wide enough for live mode's floor
        half = GROUND["half"]
        add_box(w, "Ground", (0.0, 0.0, -0.75), (2.0 * half, 2.0 * half, 0.5), colls["Walls"])
    for i in range(28):                                  # props: what gets culled
        s = rng.uniform(0.25, 1.0)
        add_box(w, f"Prop.{i:03d}", (rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(0, 1.5)),
                (s, s * rng.uniform(0.5, 1.5), s), colls["Sub" if i % 4 == 0 else "Props"],
                rng.uniform(0, math.pi))
    for i in range(4 if "scene_animated" in w.kinds else 0):      # animated props
        o = add_box(w, f"Mover.{i:03d}", (0, 0, 0), (0.6, 0.6, 0.6), colls["Moving"])
        for f in (FRAMES[0], (FRAMES[0] + FRAMES[1]) // 2, FRAMES[1]):
            o.location = (rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(0, 1.5))
            o.keyframe_insert("location", frame=f)
    if "scene_parent" in w.kinds:                        # props carried by an animated parent
        carrier = bpy.data.objects.new("Carrier", None)
        colls["Moving"].objects.link(carrier)
        for f in (FRAMES[0], FRAMES[1]):
            carrier.location = (rng.uniform(-6, 6), rng.uniform(-6, 6), 0)
            carrier.rotation_euler = (0, 0, rng.uniform(0, 2 * math.pi))
            carrier.keyframe_insert("location", frame=f)
            carrier.keyframe_insert("rotation_euler", frame=f)
        for i in range(2):
            o = add_box(w, f"Carried.{i:03d}", (rng.uniform(-2, 2), rng.uniform(-2, 2), 0.5), (0.5, 0.5, 0.5),
                        colls["Props"])
            o.parent = carrier
        o = add_box(w, "Follower", (rng.uniform(-2, 2), rng.uniform(-2, 2), 0.8), (0.4, 0.4, 0.4), colls["Props"])
        c = o.constraints.new("COPY_LOCATION")
        c.target, c.use_offset = carrier, True
    if "scene_particles" in w.kinds:                     # hair particles instancing a box
        em = add_box(w, "Emitter", (rng.uniform(-6, 6), rng.uniform(-6, 6), 0.2), (0.5, 0.5, 0.3), colls["Props"])
        src = add_box(w, "HairSource", (rng.uniform(-9, 9), rng.uniform(-9, 9), 0.3), (0.3, 0.3, 0.3),
                      colls["Props"])
        em.modifiers.new("hair", "PARTICLE_SYSTEM")
        ps = em.particle_systems[0].settings
        ps.type, ps.count, ps.hair_length = "HAIR", 4, 1.0
        ps.render_type, ps.instance_object, ps.particle_size = "OBJECT", src, 2.5
        ps.display_method = "RENDER"
    if "scene_hair_collection" in w.kinds:               # hair instancing a collection (excluded itself)
        hair_lib = bpy.data.collections.new("HairLib")
        scene.collection.children.link(hair_lib)
        add_box(w, "HairPiece", (0, 0, 0), (0.3, 0.3, 0.6), hair_lib)
        add_box(w, "HairPiece.001", (0.5, 0, 0), (0.2, 0.2, 0.2), hair_lib)
        bpy.context.view_layer.layer_collection.children["HairLib"].exclude = True
        em = add_box(w, "HairEmitter", (rng.uniform(-6, 6), rng.uniform(-6, 6), 0.2), (0.6, 0.6, 0.2),
                     colls["Props"])
        em.modifiers.new("hair", "PARTICLE_SYSTEM")
        ps = em.particle_systems[0].settings
        ps.type, ps.count, ps.hair_length = "HAIR", 3, 1.0
        ps.render_type, ps.instance_collection, ps.particle_size = "COLLECTION", hair_lib, 2.0
        ps.display_method = "RENDER"
    if "scene_verts" in w.kinds:                         # a vertex instancer: points, and a child box
        pts = bpy.data.meshes.new("VertPoints")
        pts.from_pydata([(rng.uniform(-8, 8), rng.uniform(-8, 8), 0.4) for _ in range(3)], [], [])
        vi = bpy.data.objects.new("VertInstancer", pts)
        colls["Props"].objects.link(vi)
        vi.instance_type = "VERTS"
        new_id(w, vi)
        child = add_box(w, "VertChild", (0, 0, 0), (0.5, 0.5, 0.5), colls["Props"])
        child.parent = vi
    if "scene_modifiers" in w.kinds:                     # evaluated meshes larger than their data
        for o in [o for o in colls["Props"].objects if o.name.startswith("Prop.")][:3]:
            arr = o.modifiers.new("array", "ARRAY")
            arr.count, arr.relative_offset_displace = 4, (1.5, 0.0, 0.0)
    if "scene_curves" in w.kinds:                        # geometry that is not a mesh
        txt = bpy.data.objects.new("Label", bpy.data.curves.new("Label", "FONT"))
        txt.data.body, txt.data.extrude, txt.data.size = "OCC", 0.1, 1.5
        txt.location, txt.rotation_euler = (rng.uniform(-6, 6), rng.uniform(-6, 6), 0.5), (math.pi / 2, 0, 0)
        colls["Props"].objects.link(txt)
        new_id(w, txt)
        cu = bpy.data.curves.new("Pipe", "CURVE")
        cu.dimensions, cu.bevel_depth = "3D", 0.15
        sp = cu.splines.new("POLY")
        sp.points.add(2)
        for p, co in zip(sp.points, [(-3, 0, 0.3), (0, 2, 0.6), (3, 0, 0.3)], strict=True):
            p.co = (*co, 1.0)
        pipe = bpy.data.objects.new("Pipe", cu)
        pipe.location = (rng.uniform(-5, 5), rng.uniform(-5, 5), 0)
        colls["Props"].objects.link(pipe)
        new_id(w, pipe)
    if "scene_deform" in w.kinds:                        # changes with the frame, without an edit
        o = add_box(w, "Driven", (0, rng.uniform(-6, 6), 0.5), (0.6, 0.6, 0.6), colls["Props"])
        fc = o.driver_add("location", 0)
        fc.driver.type, fc.driver.expression = "SCRIPTED", "sin(frame / 6) * 7"
        o = add_box(w, "Shaped", (rng.uniform(-6, 6), rng.uniform(-6, 6), 0.3), (0.6, 0.6, 0.6), colls["Props"])
        o.shape_key_add(name="Basis")
        up = o.shape_key_add(name="Up", from_mix=False)
        for p in up.data:
            if p.co.z > 0:
                p.co.z += 4.0
        for f, v in ((FRAMES[0], 0.0), (FRAMES[1], 1.0)):
            up.value = v
            up.keyframe_insert("value", frame=f)
    lib = bpy.data.collections.new("Lib")              # a collection instance
    scene.collection.children.link(lib)
    add_box(w, "LibPart", (0, 0, 0), (0.5, 0.5, 0.8), lib)
    add_box(w, "LibPart.001", (0.6, 0, 0), (0.3, 0.3, 0.3), lib)
    bpy.context.view_layer.layer_collection.children["Lib"].exclude = True
    inst = bpy.data.objects.new("Instance", None)
    inst.instance_type, inst.instance_collection = "COLLECTION", lib
    inst.location = (rng.uniform(-6, 6), rng.uniform(-6, 6), 0)
    colls["Props"].objects.link(inst)
    new_id(w, inst)
    gn = add_box(w, "Scatter", (rng.uniform(2, 6), rng.uniform(-3, 3), 0.3), (0.4, 0.4, 0.4), colls["Props"])
    if "scene_gn" in w.kinds:
        gn.modifiers.new("scatter", "NODES").node_group = scatter_group()
    if "scene_gn_object" in w.kinds:                     # geometry nodes instancing an object
        src = add_box(w, "GNSource", (rng.uniform(-6, 6), rng.uniform(-6, 6), 0.3), (0.4, 0.4, 0.7),
                      colls["Props"])
        host = add_box(w, "GNHost", (rng.uniform(-6, 6), rng.uniform(-6, 6), 0.2), (0.3, 0.3, 0.3),
                       colls["Props"])
        host.modifiers.new("objscatter", "NODES").node_group = object_scatter_group(src)
    other = scene.view_layers.new("Other")              # a second view layer
    other.layer_collection.children["Lib"].exclude = True
    if "HairLib" in other.layer_collection.children:
        other.layer_collection.children["HairLib"].exclude = True
    if "scene_second" in w.kinds:                        # another scene, sharing walls and props
        second = bpy.data.scenes.new("Second")
        second.frame_start, second.frame_end = FRAMES
        for name in ("Walls", "Props"):
            second.collection.children.link(colls[name])
        cam2 = bpy.data.objects.new("cam2", bpy.data.cameras.new("cam2"))
        second.collection.objects.link(cam2)
        second.camera = cam2
        place_camera(w, cam2)
        second.view_layers.new("Second Other")
    other.layer_collection.children["Props"].children["Sub"].exclude = True
    place_camera(w, cam)
    if addon_enabled():
        scene.occ.source = "CAMERA"
        scene.occ.hide_in = HIDE_IN["mode"]
    bpy.context.view_layer.update()
    w.model = read_model(w)
    push_undo(w, "build")


def place_camera(w, cam):
    """Somewhere around or inside the scene, looking at a point near its middle."""
    from mathutils import Vector
    rng = w.rng
    a, d = rng.uniform(0, 2 * math.pi), rng.choice([rng.uniform(11, 17), rng.uniform(2, 9)])
    cam.location = (d * math.cos(a), d * math.sin(a), rng.uniform(0.5, 5))
    target = Vector((rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(0, 1)))
    direction = target - cam.location
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


# --------------------------------------------------------------------------- model of the user's intent

def scene_objects():
    """``{wf_id: obj}`` of the objects this harness made (bpy.data order: by name)."""
    import bpy
    return {o["wf_id"]: o for o in bpy.data.objects if "wf_id" in o}


def layer_collections(vl):
    """``[(path names, LayerCollection)]`` below the view layer's root, depth first."""
    out = []

    def walk(lc, path):
        for c in lc.children:
            out.append((path + (c.name,), c))
            walk(c, path + (c.name,))
    walk(vl.layer_collection, ())
    return out


def read_model(w):
    """The user's intent, read from Blender where nothing but the user has acted yet."""
    import bpy
    scene = bpy.context.scene
    model = {"objects": {}, "coll_monitor": {}, "lc": {}, "exclude": None, "exclude_children": True}
    for wid, o in scene_objects().items():
        model["objects"][wid] = object_intent(o)
    for c in bpy.data.collections:
        model["coll_monitor"][c.name] = c.hide_viewport
    for vl in scene.view_layers:
        for path, lc in layer_collections(vl):
            model["lc"][(vl.name, path)] = [lc.hide_viewport, lc.exclude]
    if addon_enabled():
        ex = scene.occ.exclude_collection
        model["exclude"] = ex.name if ex else None
        model["exclude_children"] = scene.occ.exclude_children
    return model


def object_intent(o, monitor=None):
    import bpy
    return {"eye": {vl.name: o.hide_get(view_layer=vl) for vl in bpy.context.scene.view_layers},
            "monitor": o.hide_viewport if monitor is None else monitor,
            "never": bool(getattr(o, "occ_never_cull", False))}


def has_base(o, vl):
    """Whether ``o`` has a base in ``vl``: one of its collections is in the view layer
    and not excluded itself (layer_collection_sync syncs the children of an excluded
    collection too).  Computed, because ``vl.objects`` is synced only on evaluation."""
    import bpy
    scene = bpy.context.scene
    included = {scene.collection.name} | {lc.collection.name for _, lc in layer_collections(vl) if not lc.exclude}
    return any(c.name in included for c in o.users_collection)


def forget_lost_bases(w):
    """Blender forgets an object's eye flag in a view layer where it loses its base
    (its collections excluded, or unlinked): the user's flag goes with it."""
    import bpy
    objs = scene_objects()
    for vl in bpy.context.scene.view_layers:
        for wid, m in w.model["objects"].items():
            o = objs.get(wid)
            if o is not None and not has_base(o, vl):
                m["eye"][vl.name] = False


def push_undo(w, message):
    import bpy
    bpy.ops.ed.undo_push(message=message)
    mirror_undo_push(w)


def mirror_undo_push(w):
    """The model's copy of an undo step Blender just took (by the harness or the add-on)."""
    del w.undo[w.undo_pos + 1:]
    w.undo.append(copy.deepcopy(w.model))
    w.undo_pos = len(w.undo) - 1
    if len(w.undo) > 30:                        # Blender keeps 32 steps; stay inside them
        del w.undo[0]
        w.undo_pos -= 1


# --------------------------------------------------------------------------- truth

def truth_camera(scene, depsgraph, size=None):
    """The scene camera as Blender renders it: its projection at the render size (or at
    ``size``), its world matrix with the scale removed (Blender ignores a camera's scale;
    a negative one still mirrors).  None when the camera's axes are degenerate (a scale
    of 0)."""
    import numpy as np

    from core import Camera
    cam = scene.camera.evaluated_get(depsgraph)
    r = scene.render
    w, h = render_size(scene) if size is None else size
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=w, y=h, scale_x=r.pixel_aspect_x,
                                           scale_y=r.pixel_aspect_y), dtype=np.float64)
    m = np.array(cam.matrix_world, dtype=np.float64)
    n = np.linalg.norm(m[:3, :3], axis=0)
    if np.any(n < 1e-9):
        return None
    m[:3, :3] /= n
    return Camera.from_matrices(np.linalg.inv(m), proj)


def render_size(scene):
    r = scene.render
    return (max(1, int(r.resolution_x * r.resolution_percentage / 100)),
            max(1, int(r.resolution_y * r.resolution_percentage / 100)))


def camera_self_check(scene, depsgraph):
    """The truth camera against Blender's own ``world_to_camera_view`` on points in view:
    a harness error if they disagree (the truth would be from another view).  Both at
    the resolution before its percentage (``view_frame``'s: the render size's rounding
    changes the aspect a little, e.g. 97x13 at 33 % renders 32x4)."""
    import numpy as np
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
    camera = truth_camera(scene, depsgraph, (scene.render.resolution_x, scene.render.resolution_y))
    cam = scene.camera.evaluated_get(depsgraph)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-8, 8, (16, 3))
    clip = np.c_[pts, np.ones(16)] @ camera.view_projection().T
    ndc = clip[:, :2] / clip[:, 3:4]
    # in front, and in or near the frame: mathutils works in float32, which a
    # point near the camera plane would blow up
    ok = (clip[:, 3] > 0.5) & np.all(np.abs(ndc) < 2, axis=1)
    ndc = ndc[ok]
    ref = np.array([world_to_camera_view(scene, cam, Vector(p))[:2] for p in pts[ok]]) * 2 - 1
    bad = np.abs(ndc - ref).max() if len(ref) else 0.0
    return bad < 1e-3, float(bad)


def truth_visible(w):
    """Names of the objects that cover a pixel when nothing the add-on hid is hidden,
    or None when the camera is degenerate.  ``(visible names, camera error)``."""
    import bpy
    import numpy as np

    from core import Scene
    context = bpy.context
    scene = context.scene
    stand_in = {}                                   # temporary copy name -> the object it stands for
    model = w.model["objects"]
    def stand_in_for(o, parent=None):
        c = o.copy()
        clear_addon_record(c)
        c.hide_viewport = model.get(o.get("wf_id"), {}).get("monitor", False) if hidden_by_addon(o) \
            else o.hide_viewport
        if parent is not None:
            c.parent = parent
        for coll in o.users_collection:
            coll.objects.link(c)
        for vl in scene.view_layers:
            if vl.objects.get(c.name) is not None and o.hide_get(view_layer=vl):
                c.hide_set(True, view_layer=vl)
        stand_in[c.name] = o.name
        if o.instance_type in ("VERTS", "FACES"):      # its children are what it repeats
            for child in o.children:
                stand_in_for(child, c)

    for o in list(scene.objects):
        if "wf_id" in o and hidden_by_addon(o):
            stand_in_for(o)
    try:
        context.view_layer.update()
        dg = context.evaluated_depsgraph_get()
        camera = truth_camera(scene, dg) if scene.camera else None
        if camera is None:
            return None, None
        cam_ok = camera_self_check(scene, dg)
        names, meshes, matrices, solid = [], [], [], []
        drawn = {}    # the depsgraph also evaluates what eye icons hide; Blender draws what visible_get says
        for inst in dg.object_instances:
            ob = inst.object
            if ob.type not in GEOMETRY:
                continue
            owner_obj = (inst.parent if inst.is_instance and inst.parent is not None else ob).original
            owner = owner_obj.name
            if owner not in drawn:
                drawn[owner] = owner_obj.visible_get(view_layer=context.view_layer)
            if not drawn[owner]:
                continue
            seen_as = [owner]
            if inst.is_instance and (owner_obj.instance_type in SOURCE_HIDES_INSTANCES
                                     or hair_collection_member(owner_obj, ob.original)):
                seen_as.append(ob.original.name)       # hiding the source would hide this instance
            if inst.is_instance and ob.original == owner_obj and not hasattr(bpy.types.Object, "evaluated_geometry"):
                # Blender 4.2: reading a mesh geometry nodes made, while iterating, crashed
                # it now and then (seed 5020); the add-on leaves those meshes out there too
                # (its instancer is kept visible and occludes nothing), so the truth does
                continue
            mesh = ob.to_mesh()
            if mesh is None:
                ob.to_mesh_clear()
                continue
            try:
                mesh.calc_loop_triangles()
                v = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
                mesh.vertices.foreach_get("co", v)
                f = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
                mesh.loop_triangles.foreach_get("vertices", f)
            finally:
                ob.to_mesh_clear()
            v, f = v.reshape(-1, 3).astype(np.float64), f.reshape(-1, 3).astype(np.int64)
            m = np.array(inst.matrix_world, dtype=np.float64)
            if not np.all(np.isfinite(m)):
                continue                                 # Blender draws nothing of it
            bad = ~np.all(np.isfinite(v), axis=1)
            if bad.any():                                # nor the triangles of a NaN vertex
                f = f[~bad[f].any(axis=1)]
                v = np.where(bad[:, None], 0.0, v)
            if not len(f):
                continue
            display = ob.display_type
            if display == "BOUNDS" and len(v):           # drawn as its box's edges
                lo, hi = v.min(axis=0), v.max(axis=0)
                v = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
                f = BOX_FACES
            names.append(tuple(stand_in.get(n, n) for n in seen_as))
            meshes.append((v, f))
            matrices.append(m)
            solid.append(display in ("SOLID", "TEXTURED"))
        if not names:
            return set(), cam_ok
        truth_scene = Scene.from_arrays([str(i) for i in range(len(names))], meshes,
                                        np.arange(len(names)), np.array(matrices))
        w.last_truth = names                          # for debugging a failure by hand
        seen = w.truth_pool.submit(_truth, truth_scene, render_size(scene), camera,
                                   np.array(solid, dtype=bool)).result()
        return {n for i in np.flatnonzero(seen) for n in names[i]}, cam_ok
    finally:
        for cname in stand_in:
            bpy.data.objects.remove(bpy.data.objects[cname], do_unlink=True)
        context.view_layer.update()


def hair_collection_member(owner, src):
    """Whether ``src`` is instanced by a particle system of ``owner`` that instances a
    collection: such instances vanish when their object is hidden (monitor), as a
    collection instance's do (an object's hair instances stay drawn)."""
    for ps in owner.particle_systems:
        c = ps.settings.instance_collection
        if ps.settings.render_type == "COLLECTION" and c is not None and src.name in c.all_objects:
            return True
    return False


_GL = {}          # the harness's own GL context, made and used on its own thread


def _truth(scene, resolution, camera, solid):
    """On the harness's own GL thread: the object-ID truth.  Objects drawn as wire or
    bounds hide nothing: each is seen where its surface is nearer than every solid one."""
    import numpy as np

    from core import Culler
    from core.gl import create_context
    if "ctx" not in _GL:
        _GL["ctx"] = create_context()
    culler = Culler(scene, resolution, ctx=_GL["ctx"])
    try:
        if solid.all():
            return culler.truth(camera)
        keep = np.flatnonzero(solid)
        ids = culler.renderer.object_ids(camera, objects=keep)
        seen = np.zeros(len(solid), dtype=bool)
        seen[ids[ids >= 0]] = True
        for k in np.flatnonzero(~solid):
            seen[k] = bool((culler.renderer.object_ids(camera, objects=np.append(keep, k)) == k).any())
        return seen
    finally:
        culler.close()


# --------------------------------------------------------------------------- checks

def predicted_visible(o, vl, intent, visible_colls):
    """What Blender shows per the user's flags: not hidden (monitor, or eye in this view
    layer) and in at least one collection whose whole path is included and shown."""
    if intent["monitor"] or intent["eye"].get(vl.name, False):
        return False
    return any(c.name in visible_colls for c in o.users_collection)


def visible_collections(scene, vl):
    out = {scene.collection.name}

    def walk(lc, shown):
        for c in lc.children:
            # the eye and the monitor are inherited; exclude is not (Blender's
            # layer_collection_sync: excluding a parent excludes its children by
            # setting their own flags, and a child included again is drawn)
            here = shown and not c.hide_viewport and not c.collection.hide_viewport
            if here and not c.exclude:
                out.add(c.collection.name)
            walk(c, here)
    walk(vl.layer_collection, True)
    return out


def check_state(w, after_restore=False):
    """(b), (c) and visibility consistency: a list of problems."""
    import bpy
    scene = bpy.context.scene
    problems = []
    objs = scene_objects()
    model = w.model
    for wid, m in model["objects"].items():
        o = objs.get(wid)
        if o is None:
            problems.append(f"b: object #{wid} the user never deleted is gone")
            continue
        ours = addon_hidden(o)
        if after_restore and ours:
            problems.append(f"c: '{o.name}' still recorded as hidden by the add-on after Restore")
        if o.hide_viewport != m["monitor"] and not (ours and o.hide_viewport):
            problems.append(f"b: '{o.name}' monitor (hide_viewport) is {o.hide_viewport}, "
                            f"the user set {m['monitor']}" + (" (add-on record set)" if ours else ""))
        for vl in scene.view_layers:
            if vl.objects.get(o.name) is not None and o.hide_get(view_layer=vl) != m["eye"][vl.name]:
                problems.append(f"b: '{o.name}' eye in '{vl.name}' is {o.hide_get(view_layer=vl)}, "
                                f"the user set {m['eye'][vl.name]}")
        if addon_enabled() and bool(o.occ_never_cull) != m["never"]:
            problems.append(f"b: '{o.name}' never-cull is {o.occ_never_cull}, the user set {m['never']}")
    for wid, o in objs.items():
        if wid not in model["objects"] and o.name in scene.objects:
            problems.append(f"b: '{o.name}' (#{wid}) exists but the user never made it")
    for c in bpy.data.collections:
        if c.name in model["coll_monitor"] and c.hide_viewport != model["coll_monitor"][c.name]:
            problems.append(f"b: collection '{c.name}' monitor is {c.hide_viewport}")
    space = window_view()
    for vl in scene.view_layers:
        for path, lc in layer_collections(vl):
            want = model["lc"].get((vl.name, path))
            if want is not None and [lc.hide_viewport, lc.exclude] != want:
                problems.append(f"b: layer collection {'/'.join(path)} in '{vl.name}' is "
                                f"eye-hidden/excluded {[lc.hide_viewport, lc.exclude]}, the user set {want}")
        vis = visible_collections(scene, vl)
        for wid, m in model["objects"].items():
            o = objs.get(wid)
            if o is None or hidden_by_addon(o) or o.name not in scene.objects:
                continue
            want = predicted_visible(o, vl, m, vis)
            if o.visible_get(view_layer=vl) != want:
                problems.append(f"b: '{o.name}' visible_get() in '{vl.name}' is {not want}, "
                                f"the user's flags say {want} (collections "
                                f"{[c.name for c in o.users_collection]}; layer collections "
                                f"{[('/'.join(p), lc.exclude, lc.hide_viewport) for p, lc in layer_collections(vl)]})")
            if vl == bpy.context.view_layer and space is not None \
                    and o.visible_get(view_layer=vl, viewport=space) != want:
                # what the add-on did not hide, the window's 3D view draws as the flags say
                # (its own local view holds every object: new ones, after undo and reload)
                problems.append(f"b: '{o.name}' drawn in the window's 3D view: "
                                f"{o.visible_get(view_layer=vl, viewport=space)}, the user's flags say {want} "
                                f"(local view {space.local_view is not None}, record {addon_hidden(o)}, "
                                f"monitor {o.hide_viewport}, layer {vl.name})")
    if any("drawn in the window's 3D view" in p for p in problems):
        problems.append("d: state: " + local_view_state())
    if addon_enabled():
        ex = scene.occ.exclude_collection
        if (ex.name if ex else None) != model["exclude"] or scene.occ.exclude_children != model["exclude_children"]:
            problems.append(f"b: exclude collection setting is {ex.name if ex else None}/"
                            f"{scene.occ.exclude_children}, the user set {model['exclude']}/"
                            f"{model['exclude_children']}")
    return problems


def check_cull(w):
    """(a) and (e) after a cull: a list of problems."""
    import bpy
    scene = bpy.context.scene
    problems = []
    seen, cam_ok = truth_visible(w)
    if cam_ok is not None and not cam_ok[0]:
        problems.append(f"harness: truth camera differs from world_to_camera_view by {cam_ok[1]:.2e}")
    if seen is not None:
        w.stats["truth_checks"] += 1
        w.stats["hidden_at_checks"] += sum(1 for o in scene.objects if hidden_by_addon(o))
        w.stats["visible_at_checks"] += len(seen)
        w.stats["floor_checks"] += int(hidden_over_a_floor())
        wrong = sorted(o.name for o in scene.objects if o.name in seen and hidden_by_addon(o))
        if wrong:
            problems.append(f"a: hidden by the add-on but visible from the camera: {wrong}")
    ex = scene.occ.exclude_collection
    keep = set()
    if ex is not None:
        keep = {o.name for o in (ex.all_objects if scene.occ.exclude_children else ex.objects)}
    bad = sorted(o.name for o in scene.objects if hidden_by_addon(o)
                 and (o.occ_never_cull or o.name in keep))
    if bad:
        problems.append(f"e: never-cull or exclude-collection objects hidden: {bad}")
    broken = sorted(o.name for o in scene.objects if hidden_by_addon(o) and has_nan(o))
    if broken:
        problems.append(f"e: objects with a NaN are hidden (they must stay visible): {broken}")
    return problems


def hidden_over_a_floor():
    """Whether the set the add-on shows holds for an envelope that keeps its eyes above a
    floor (:func:`core.envelope.floor_cut`) and hides something."""
    import bpy
    mod = sys.modules.get(ADDON_MODULE + ".occ_addon.session")
    shown = getattr(getattr(mod, "SESSION", None), "shown", None) if addon_enabled() else None
    envelope = getattr(shown, "envelope", None)
    return getattr(envelope, "floor", None) is not None and getattr(shown, "camera", None) is not None \
        and any(hidden_by_addon(o) for o in bpy.context.scene.objects)


def check_truth_camera(w):
    """Harness self-check (validate mode): the truth's camera is Blender's."""
    _, cam_ok = truth_visible(w)
    if cam_ok is not None and not cam_ok[0]:
        return [f"harness: truth camera differs from world_to_camera_view by {cam_ok[1]:.2e}"]
    return []


# --------------------------------------------------------------------------- steps

def pick(w, hidden_first=0.5, animated=None):
    """A random object of the scene, preferring one the add-on hid (where bugs live)."""
    import bpy
    objs = [o for o in bpy.context.scene.objects if "wf_id" in o]
    if animated is not None:
        objs = [o for o in objs if (o.animation_data is not None) == animated]
    if not objs:
        return None
    ours = [o for o in objs if hidden_by_addon(o)]
    if w.rng.random() < hidden_first and ours:              # one draw either way (--plain replays)
        return w.rng.choice(ours)
    return w.rng.choice(objs)


def in_view_point(w):
    """A point between the camera and what it looks at: likely in plain view."""
    import bpy
    from mathutils import Vector
    cam = bpy.context.scene.camera
    m = cam.matrix_world.normalized()
    fwd = -(m.to_3x3() @ Vector((0, 0, 1)))
    p = m.translation + fwd * w.rng.uniform(2.5, 6) + Vector((w.rng.uniform(-0.6, 0.6),) * 3)
    return tuple(p)


def user_collections():
    import bpy
    return [c for c in bpy.data.collections if c.name in ("Walls", "Props", "Sub", "Moving")]


def link_like(src, obj):
    import bpy
    colls = list(src.users_collection) or [bpy.context.scene.collection]
    for c in colls:
        c.objects.link(obj)


def local_view_state():
    """The add-on's local-view bookkeeping against the window's, for a failure's report."""
    import bpy
    space, win = window_view(), bpy.context.window
    local = space.local_view is not None if space else None
    out = [f"window layer {win.view_layer.name if win else None}, context layer {bpy.context.view_layer.name}",
           f"space {space.as_pointer() if space else None} local view {local}"]
    lv = sys.modules.get(ADDON_MODULE + ".occ_addon.localview")
    vis = sys.modules.get(ADDON_MODULE + ".occ_addon.visibility")
    if lv is not None:
        out.append("own " + repr({k: (v["layer"], len(v["uids"])) for k, v in lv._own.items()}))
    if vis is not None:
        out.append(f"view record pointer {vis._view['pointer']}")
    out.append(f"live {live_on()}")
    return "; ".join(out)


def switch_view_layer(target):
    """The window shows another view layer (the add-on re-evaluates transforms once after a
    switch); a window evaluates the layer it shows before drawing it: so does this step."""
    import bpy
    bpy.context.window.view_layer = target
    bpy.context.view_layer.update()
    if addon_enabled():                        # the message bus's call, as the window's event loop makes it
        sys.modules[f"{ADDON_MODULE}.occ_addon.localview"].on_window_change()


# Each step applies one user action and returns a short description for the history.
# Scene steps take ``(w, kind)``; object steps ``(w, kind, obj)``, the object drawn by
# :func:`pick` first (the draws of the generator stay in the same order).

def step_cull(w, kind):
    import bpy
    scene = bpy.context.scene
    try:
        r = bpy.ops.occ.cull()
        return f"cull -> {sorted(r)}"
    except RuntimeError as e:                  # an ERROR report: fine unless it is our bug
        if "failed" in str(e):
            raise
        broken = [o.name for o in scene.objects if o.name in str(e) and has_nan(o)]
        if broken and "nothing to cull" not in str(e):  # the bad one left out, nothing else to cull: fine
            w.pending.append(f"g: one object with a NaN ({broken}) stopped the whole cull: {e}")
        return f"cull -> report: {e}"


def step_restore(w, kind):
    import bpy
    return f"restore -> {sorted(bpy.ops.occ.restore())}"


def step_live(w, kind):
    import bpy
    live = live_module()
    if bpy.context.scene.occ.live:             # what occ.live does when it is on
        live.stop(bpy.context)
        bpy.ops.occ.restore()
        return "live off"
    live.start(bpy.context)
    return "live on"


def step_camera_move(w, kind):
    import bpy
    cam = bpy.context.scene.camera
    place_camera(w, cam)
    return f"camera to {tuple(round(x, 2) for x in cam.location)}"


def step_camera_nudge(w, kind):
    """A small move between live ticks (checked before them)."""
    import bpy
    import mathutils
    cam = bpy.context.scene.camera
    step = mathutils.Vector([w.rng.gauss(0.0, 1.0) for _ in range(3)])
    step.length = w.rng.choice([0.02, 0.2, 1.0, 3.0])
    cam.location += step
    cam.rotation_euler.z += math.radians(w.rng.uniform(-8.0, 8.0))
    return f"camera nudged by {step.length:.2f} to {tuple(round(x, 2) for x in cam.location)}"


def step_camera_scale(w, kind):
    import bpy
    s = w.rng.choice([(1, 1, 1), (1, 1, 1), (0.01, 0.01, 0.01), (-1, 1, 1), (2, 2, 2), (1, 0.5, 3),
                      (100, 100, 100), (1, 1, 0)])
    bpy.context.scene.camera.scale = s
    return f"camera scale {s}"


def step_camera_lens(w, kind):
    import bpy
    rng, d = w.rng, bpy.context.scene.camera.data
    d.type = rng.choice(["PERSP", "PERSP", "ORTHO"])
    d.lens, d.ortho_scale = rng.uniform(18, 85), rng.uniform(6, 25)
    d.clip_start, d.clip_end = rng.choice([(0.1, 100.0), (0.5, 14.0), (0.01, 1000.0)])
    d.shift_x, d.shift_y = rng.uniform(-0.3, 0.3), rng.uniform(-0.2, 0.2)
    d.sensor_fit = rng.choice(["AUTO", "HORIZONTAL", "VERTICAL"])
    said = (f"camera {d.type} lens {d.lens:.0f} clip {d.clip_start:g}-{d.clip_end:g} "
            f"shift {d.shift_x:.2f},{d.shift_y:.2f} fit {d.sensor_fit}")
    if rng.random() < 0.5:
        # the render size too (issue 30: a Cull after 160x60 -> 200x60 hid a seen object):
        # wide, tall, tiny and odd sizes, percentages and pixel aspects; the truth is drawn
        # at the render size (render_size), as the add-on culls
        r = bpy.context.scene.render
        r.resolution_x, r.resolution_y = rng.choice(RENDER_SIZES)
        r.resolution_percentage = rng.choice([100, 100, 50, 33, 150])
        r.pixel_aspect_x, r.pixel_aspect_y = rng.choice([(1, 1), (1, 1), (2, 1), (1, 2), (1.5, 1)])
        said += (f", render {r.resolution_x}x{r.resolution_y} {r.resolution_percentage} % "
                 f"aspect {r.pixel_aspect_x:g}:{r.pixel_aspect_y:g}")
    return said


# render sizes a camera_lens step may set (Blender keeps a side at 4 or more)
RENDER_SIZES = ((160, 60), (200, 60), (200, 66), (201, 60), (300, 60), (100, 30), (400, 120), (60, 200),
                (97, 13), (13, 97), (333, 4), (256, 4), (4, 256), (64, 5), (5, 64), (50, 8), (8, 50), (7, 4),
                (4, 4), (199, 61), (320, 180))


def step_frame(w, kind):
    import bpy
    f = w.rng.randint(*FRAMES)
    bpy.context.scene.frame_set(f)
    return f"frame {f}"


def step_view_layer(w, kind):
    """A new view layer (everything shown there), the extra one removed, or another one active."""
    import bpy
    rng, scene, model, vl = w.rng, bpy.context.scene, w.model, bpy.context.view_layer
    if len(scene.view_layers) < 3 and rng.random() < 0.3:
        new = scene.view_layers.new("Third")
        if "instanced_member_drawn" in KNOWN_UNFIXED:
            new.layer_collection.children["Lib"].exclude = True
        if "hair_member_drawn" in KNOWN_UNFIXED and "HairLib" in new.layer_collection.children:
            new.layer_collection.children["HairLib"].exclude = True
        for m in model["objects"].values():
            m["eye"][new.name] = False
        for path, lc in layer_collections(new):
            model["lc"][(new.name, path)] = [lc.hide_viewport, lc.exclude]
        switch_view_layer(new)
        return f"new view layer '{new.name}', active"
    if len(scene.view_layers) > 2 and rng.random() < 0.3:
        gone = next(v for v in scene.view_layers if v.name.startswith("Third"))
        if gone == vl:
            switch_view_layer(scene.view_layers[0])
        name = gone.name
        scene.view_layers.remove(gone)
        for m in model["objects"].values():
            m["eye"].pop(name, None)
        model["lc"] = {k: v for k, v in model["lc"].items() if k[0] != name}
        return f"view layer '{name}' removed, active '{bpy.context.view_layer.name}'"
    other = [v for v in scene.view_layers if v != vl]
    switch_view_layer(rng.choice(other))
    return f"view layer -> {bpy.context.view_layer.name}"


def step_add(w, kind):
    import bpy
    rng = w.rng
    c = rng.choice(user_collections() + [bpy.context.scene.collection])
    p = in_view_point(w) if rng.random() < 0.5 else (rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(0, 1.5))
    o = add_box(w, "Added", p, (0.5, 0.5, 0.5), c, rng.uniform(0, 3))
    w.model["objects"][o["wf_id"]] = object_intent(o)
    return f"add '{o.name}' in {c.name} at {tuple(round(x, 2) for x in p)}"


def step_settings(w, kind):
    """The add-on's own choices: strategy, accuracy."""
    import bpy
    occ = bpy.context.scene.occ
    strategies = [i.identifier for i in occ.bl_rna.properties["strategy"].enum_items]
    occ.strategy = w.rng.choice(strategies)
    occ.preset = w.rng.choice([i.identifier for i in occ.bl_rna.properties["preset"].enum_items])
    return f"strategy {occ.strategy}, accuracy {occ.preset}"


def step_exclude_setting(w, kind):
    import bpy
    occ = bpy.context.scene.occ
    c = w.rng.choice(user_collections() + [None])
    occ.exclude_collection = c
    occ.exclude_children = w.rng.random() < 0.5
    w.model["exclude"], w.model["exclude_children"] = (c.name if c else None), occ.exclude_children
    return f"exclude collection {c.name if c else None} children {occ.exclude_children}"


def step_layer_collection(w, kind):
    """coll_eye / coll_exclude: a layer collection's eye or exclude box in the active view layer."""
    import bpy
    scene, vl = bpy.context.scene, bpy.context.view_layer
    fixed = {"Lib"} | ({"HairLib"} if "hair_member_drawn" in KNOWN_UNFIXED else set())
    path, lc = w.rng.choice([x for x in layer_collections(vl) if x[0][0] not in fixed])
    if kind == "coll_eye":
        lc.hide_viewport = not lc.hide_viewport
    else:
        lc.exclude = not lc.exclude
    for v in scene.view_layers:                 # Blender's own consequences (children of an excluded one)
        for p2, lc2 in layer_collections(v):
            w.model["lc"][(v.name, p2)] = [lc2.hide_viewport, lc2.exclude]
    forget_lost_bases(w)
    return f"{kind} {'/'.join(path)} in '{vl.name}' -> {[lc.hide_viewport, lc.exclude]}"


def step_collection_monitor(w, kind):
    c = w.rng.choice(user_collections())
    c.hide_viewport = not c.hide_viewport
    w.model["coll_monitor"][c.name] = c.hide_viewport
    return f"collection monitor {c.name} -> {c.hide_viewport}"


def step_object_move(w, kind, o):
    rng = w.rng
    p = in_view_point(w) if rng.random() < 0.5 else (rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(0, 1.5))
    o.location = p
    return f"move '{o.name}' to {tuple(round(x, 2) for x in p)}"


def step_hide_eye(w, kind, o):
    import bpy
    vl, name = bpy.context.view_layer, o.name
    if vl.objects.get(name) is None:
        return f"hide_eye '{name}': not in view layer"
    state = not o.hide_get()
    o.hide_set(state)
    w.model["objects"][o["wf_id"]]["eye"][vl.name] = state
    return f"eye '{name}' hidden={state}"


def step_hide_monitor(w, kind, o):
    """A click toggles what the icon shows; the UI evaluates the depsgraph (redraw) after each click."""
    import bpy
    m, name = w.model["objects"][o["wf_id"]], o.name
    o.hide_viewport = not o.hide_viewport
    m["monitor"] = o.hide_viewport
    if w.rng.random() < 0.3:
        bpy.context.view_layer.update()
        o.hide_viewport = not o.hide_viewport
        m["monitor"] = o.hide_viewport
        return f"monitor '{name}' clicked twice -> hidden={o.hide_viewport}"
    return f"monitor '{name}' clicked -> hidden={o.hide_viewport}"


def step_object_scale(w, kind, o):
    rng = w.rng
    sx = rng.choice([1.0, -1.0, 0.3, 3.0])            # negative: a mirrored object
    o.scale = (sx * abs(o.scale[0]) if sx < 0 else sx, o.scale[1], rng.choice([o.scale[2], 2.5]))
    return f"scale '{o.name}' to {tuple(round(x, 2) for x in o.scale)}"


def step_mesh_edit(w, kind, o):
    """A script (or edit mode) reshapes the mesh data: taller or flatter, a little off centre."""
    import bpy
    name = o.name
    if o.type != "MESH" or not len(o.data.vertices):
        return f"mesh_edit '{name}': no mesh"
    sz, dx = w.rng.choice([0.2, 0.5, 2.0, 4.0]), w.rng.uniform(-1.0, 1.0)
    co = [0.0] * (3 * len(o.data.vertices))
    o.data.vertices.foreach_get("co", co)
    co = [c * sz if i % 3 == 2 else c + (dx if i % 3 == 0 else 0.0) for i, c in enumerate(co)]
    o.data.vertices.foreach_set("co", co)
    o.data.update()
    users = [u.name for u in bpy.data.objects if u.data == o.data]
    return f"mesh of '{name}' z x{sz}, x {dx:+.2f} (mesh users {users})"


def step_display_type(w, kind, o):
    name = o.name
    if "wire_instanced_member" in KNOWN_UNFIXED and "Lib" in [c.name for c in o.users_collection]:
        return f"display '{name}': a member of 'Lib' stays solid ({KNOWN_UNFIXED['wire_instanced_member']})"
    o.display_type = w.rng.choice(["TEXTURED", "SOLID", "WIRE", "BOUNDS"])
    return f"display '{name}' as {o.display_type}"


def step_never_cull(w, kind, o):
    o.occ_never_cull = not o.occ_never_cull
    w.model["objects"][o["wf_id"]]["never"] = o.occ_never_cull
    return f"never cull '{o.name}' -> {o.occ_never_cull}"


def step_delete(w, kind, o):
    import bpy
    wid, name = o["wf_id"], o.name
    bpy.data.objects.remove(o, do_unlink=True)
    del w.model["objects"][wid]
    return f"delete '{name}'"


def step_rename(w, kind, o):
    name = o.name
    o.name = f"R{w.rng.randint(0, 999)}"
    return f"rename '{name}' -> '{o.name}'"


def step_rename_swap(w, kind, o):
    name = o.name
    b = pick(w, hidden_first=0.0)
    if b is None or b == o:
        return "swap: no pair"
    bname = b.name
    o.name = "wf_swap_tmp"
    b.name = name
    o.name = bname
    return f"swap names '{name}' <-> '{bname}'"


def step_rename_replace(w, kind, o):
    import bpy
    wid, name = o["wf_id"], o.name
    b = pick(w, hidden_first=0.0)
    if b is None or b == o:
        return "replace: no pair"
    bname = b.name
    bpy.data.objects.remove(o, do_unlink=True)
    del w.model["objects"][wid]
    b.name = name
    return f"delete '{name}', rename '{bname}' -> '{b.name}'"


def step_copy(w, kind, o):
    """duplicate (a copy, its mesh copied or shared) or link (a new object on the same data)."""
    import bpy
    rng, name, m = w.rng, o.name, w.model["objects"][o["wf_id"]]
    if kind == "duplicate":
        c = o.copy()                            # copies custom and add-on properties, and flags
        if rng.random() < 0.5 and c.data is not None:
            c.data = o.data.copy()
        link_like(o, c)
    else:
        c = bpy.data.objects.new(f"{name}_link", o.data)
        rng.choice(user_collections()).objects.link(c)
        if o.instance_type == "COLLECTION":
            c.instance_type, c.instance_collection = o.instance_type, o.instance_collection
    if c.animation_data is None:
        c.location = in_view_point(w) if rng.random() < 0.5 else (rng.uniform(-9, 9), rng.uniform(-9, 9), 0.5)
    new_id(w, c)
    # the user's flags of the copy: Blender copies the object's own ones (monitor,
    # never cull) and gives the new base a shown eye; the add-on's hiding is not the user's
    intent = object_intent(c, monitor=m["monitor"] if kind == "duplicate" else False)
    intent["never"] = m["never"] if kind == "duplicate" else False
    w.model["objects"][c["wf_id"]] = intent
    return f"{kind} '{name}' -> '{c.name}'"


def step_move_collection(w, kind, o):
    import bpy
    rng, name = w.rng, o.name
    dest = rng.choice(user_collections() + [bpy.context.scene.collection])
    if dest.name in [c.name for c in o.users_collection]:
        return f"move '{name}': already in {dest.name}"
    srcs = list(o.users_collection)
    dest.objects.link(o)
    if srcs and (rng.random() < 0.7 or ("instanced_member_drawn" in KNOWN_UNFIXED and srcs[0].name == "Lib")
                 or ("hair_member_drawn" in KNOWN_UNFIXED and srcs[0].name == "HairLib")):
        srcs[0].objects.unlink(o)
    forget_lost_bases(w)
    return f"move '{name}' from {[c.name for c in srcs]} to {dest.name}"


def instance_sources():
    """The objects that hair systems and geometry nodes instance, and their instancers."""
    import bpy
    srcs, hosts = [], []
    for o in bpy.context.scene.objects:
        if "wf_id" not in o:
            continue
        for ps in o.particle_systems:
            hosts.append(o)
            s = ps.settings
            srcs += [s.instance_object] if s.instance_object is not None else []
            srcs += list(s.instance_collection.all_objects) if s.instance_collection is not None else []
        for m in o.modifiers:
            if m.type == "NODES" and m.node_group is not None:
                hosts.append(o)
                srcs += [n.inputs["Object"].default_value for n in m.node_group.nodes
                         if n.bl_idname == "GeometryNodeObjectInfo" and n.inputs["Object"].default_value]
    return [o for o in srcs if "wf_id" in o], hosts


def step_instance_move(w, kind):
    """A hair system's instance object (or a member of its collection), a geometry-nodes
    instancer's object, or an instancer itself moved (or only tagged for an update, as a
    script or a driver does)."""
    rng = w.rng
    srcs, hosts = instance_sources()
    pool = srcs if srcs and (not hosts or rng.random() < 0.75) else hosts
    if not pool:
        return "instance_move: no instancing system"
    o = rng.choice(sorted(pool, key=lambda x: x.name))
    how = rng.random()
    if how < 0.15:
        o.update_tag()
        return f"instance source '{o.name}' tagged for an update"
    if how < 0.35:
        o.rotation_euler.z += rng.uniform(-1.0, 1.0)
        o.scale = (o.scale[0] * rng.choice([0.7, 1.4]),) + tuple(o.scale[1:])
        return f"instance source '{o.name}' turned and scaled"
    o.location.x += rng.uniform(-1.5, 1.5)
    o.location.y += rng.uniform(-1.5, 1.5)
    return f"instance source '{o.name}' moved to {tuple(round(x, 2) for x in o.location)}"


def step_scene_switch(w, kind):
    """The window shows the second scene (sharing walls and props), evaluated there,
    maybe a frame change or an edit of a shared object in it, then back to the first
    scene and its view layer (checks and the model are of the first scene)."""
    import bpy
    rng, win = w.rng, bpy.context.window
    second = bpy.data.scenes.get("Second")
    if second is None or win is None:
        return "scene_switch: no second scene"
    first, layer = bpy.context.scene, bpy.context.view_layer.name
    win.scene = second
    if rng.random() < 0.4 and len(second.view_layers) > 1:
        win.view_layer = rng.choice(list(second.view_layers))
    bpy.context.view_layer.update()
    what = f"scene '{second.name}' ('{bpy.context.view_layer.name}')"
    r = rng.random()
    if r < 0.3:
        f = rng.randint(*FRAMES)
        second.frame_set(f)
        what += f", frame {f}"
    elif r < 0.6:
        shared = [o for o in second.objects if "wf_id" in o and o.animation_data is None]
        if shared:
            o = rng.choice(shared)
            o.location.z += rng.uniform(-0.5, 0.5)
            bpy.context.view_layer.update()
            what += f", moved '{o.name}' there"
    win.scene = first
    back = first.view_layers.get(layer)
    if back is not None:
        switch_view_layer(back)                 # the window shows the scene's first layer again otherwise
    else:
        bpy.context.view_layer.update()
    return what + f", back to '{first.name}' ('{bpy.context.view_layer.name}')"


def step_emitter_undo(w, kind):
    """A hair emitter (or a geometry-nodes instancer) deleted, the deletion an undo step,
    undone; sometimes redone (and undone again); sometimes a frame change after it
    (what evaluates every view layer's depsgraph)."""
    import bpy
    rng = w.rng
    _, hosts = instance_sources()
    if not hosts:
        return "emitter_undo: no emitter"
    o = rng.choice(sorted(set(hosts), key=lambda x: x.name))
    wid, name = o["wf_id"], o.name
    bpy.data.objects.remove(o, do_unlink=True)
    del w.model["objects"][wid]
    if rng.random() < 0.5:
        bpy.context.view_layer.update()
    push_undo(w, "delete")
    what = [f"delete emitter '{name}'", do_undo(w, "undo")]
    if rng.random() < 0.3:
        what.append(do_undo(w, "redo"))
        if rng.random() < 0.5:
            what.append(do_undo(w, "undo"))
    if rng.random() < 0.5:
        bpy.context.view_layer.update()
    if rng.random() < 0.4:
        f = rng.randint(*FRAMES)
        bpy.context.scene.frame_set(f)
        what.append(f"frame {f}")
    return ", ".join(what)


def never_visible(w, collect=True):
    """The "Never Visible" collection; an analysis collects it first where there is none
    (and the add-on is on): a user's steps with it follow one.  None when there is none."""
    import bpy
    never = bpy.data.collections.get(NEVER_VISIBLE)
    if never is None and collect and addon_enabled():
        w.note = f"first {do_analyze(w, collect=True)}; "
        never = bpy.data.collections.get(NEVER_VISIBLE)
    elif never is None and collect and w.plain and w.plain_on:    # as far as plain Blender goes
        never = bpy.data.collections.new(NEVER_VISIBLE)
        bpy.context.scene.collection.children.link(never)
        for vl in bpy.context.scene.view_layers:
            vl.layer_collection.children[never.name].exclude = True
            w.model["lc"][(vl.name, (never.name,))] = [False, True]
        w.note = f"first an empty '{NEVER_VISIBLE}' (--plain); "
    if never is None or never.name not in bpy.context.scene.collection.children:
        return None
    return never


def step_nv_move(w, kind, o):
    """M into "Never Visible": the object's only collection is that one (excluded in
    every view layer: it has a base nowhere after)."""
    import bpy
    never, name = never_visible(w), o.name
    if never is None:
        return f"nv_move '{name}': no '{NEVER_VISIBLE}'"
    if o.name not in bpy.context.scene.objects:
        return f"nv_move '{name}': not in the scene"
    view = bpy.context.view_layer
    for b in view.objects:
        b.select_set(b == o)
    if view.objects.get(o.name) is not None:
        view.objects.active = o
    props = {p.identifier for p in bpy.ops.object.move_to_collection.get_rna_type().properties}
    where = ({"collection_uid": never.session_uid} if "collection_uid" in props                    # 5.x
             else {"collection_index": 1 + [c.name for c in bpy.context.scene.collection.children].index(never.name)})
    how = "M"
    try:
        if view.objects.get(o.name) is None or not o.select_get():
            raise RuntimeError("not selectable in this view layer")
        bpy.ops.object.move_to_collection(**where)
    except RuntimeError:
        pass
    if [c.name for c in o.users_collection] != [never.name]:     # as a drag in the outliner does
        how = "outliner"
        for c in list(o.users_collection):
            if c != never:
                c.objects.unlink(o)
        if o.name not in never.objects:
            never.objects.link(o)
    forget_lost_bases(w)
    return f"move '{name}' into '{NEVER_VISIBLE}' only ({how}) -> {[c.name for c in o.users_collection]}"


def step_nv_add(w, kind):
    """"Never Visible" included in the view layer to look at it, made the active
    collection, an object added (it lands there), and excluded again."""
    import bpy
    never = never_visible(w)
    if never is None:
        return f"nv_add: no '{NEVER_VISIBLE}'"
    view = bpy.context.view_layer
    lc = view.layer_collection.children.get(never.name)
    if lc is None:
        return f"nv_add: '{NEVER_VISIBLE}' not in '{view.name}'"
    was = lc.exclude
    lc.exclude = False                          # an excluded collection cannot be the active one
    view.active_layer_collection = lc
    p = in_view_point(w) if w.rng.random() < 0.5 else (w.rng.uniform(-9, 9), w.rng.uniform(-9, 9), 0.5)
    bpy.ops.mesh.primitive_cube_add(location=p, size=0.5)
    o = bpy.context.active_object
    o.name = "AddedNV"
    new_id(w, o)
    view.active_layer_collection = view.layer_collection
    lc.exclude = was
    for v in bpy.context.scene.view_layers:
        for p2, lc2 in layer_collections(v):
            w.model["lc"][(v.name, p2)] = [lc2.hide_viewport, lc2.exclude]
    forget_lost_bases(w)
    w.model["objects"][o["wf_id"]] = object_intent(o)
    return f"add '{o.name}' with '{NEVER_VISIBLE}' active -> {[c.name for c in o.users_collection]}"


def step_nv_duplicate(w, kind):
    """A script's linked duplicate of an object in "Never Visible", linked there only."""
    never = never_visible(w)
    if never is None:
        return f"nv_duplicate: no '{NEVER_VISIBLE}'"
    inside = sorted((o for o in never.objects if "wf_id" in o), key=lambda x: x.name)
    if not inside:
        return f"nv_duplicate: nothing in '{NEVER_VISIBLE}'"
    o = w.rng.choice(inside)
    m = w.model["objects"].get(o["wf_id"])
    c = o.copy()                                # a linked duplicate: its data shared
    never.objects.link(c)
    new_id(w, c)
    intent = object_intent(c, monitor=m["monitor"] if m else c.hide_viewport)
    intent["never"] = m["never"] if m else intent["never"]
    w.model["objects"][c["wf_id"]] = intent
    return f"linked duplicate '{o.name}' -> '{c.name}' in '{NEVER_VISIBLE}' only"


def step_bake(w, kind):
    """Bake Shot over ten frames from a random one (half the time the camera keyed to
    move through them first), Use Baked Shot on, three frames of the range shown (each
    checked against the truth)."""
    import bpy
    scene = bpy.context.scene
    a = w.rng.randint(FRAMES[0], FRAMES[1] - 9)
    keyed = ""
    cam = scene.camera
    if cam is not None and w.rng.random() < 0.5:
        for f, dx in ((a, 0.0), (a + 9, w.rng.uniform(-3.0, 3.0))):
            scene.frame_set(f)
            cam.location.x += dx
            cam.keyframe_insert("location", frame=f)
        keyed = ", camera keyed"
    try:
        r = bake_shot(w, a, a + 9)
        if not scene.occ_bake.use:
            bpy.ops.occ.bake_use()
    except RuntimeError as e:                  # an ERROR report: fine unless it is our bug
        if "failed" in str(e):
            raise
        r = f"report: {e}"
    for f in sorted(w.rng.sample(range(a, a + 10), 3), reverse=w.rng.random() < 0.5):
        scene.frame_set(f)                     # played at once, as a user checks a bake
        bpy.context.view_layer.update()
        if bake_on():
            w.stats["bake_checks"] += 1
            w.pending += check_cull(w)
    return f"bake {a}-{a + 9}{keyed} -> {r}, frame {scene.frame_current}"


def step_bake_use(w, kind):
    import bpy
    try:
        return f"bake use -> {sorted(bpy.ops.occ.bake_use())}, on: {bpy.context.scene.occ_bake.use}"
    except RuntimeError as e:                  # no bake yet: an ERROR report
        if "failed" in str(e):
            raise
        return f"bake use -> report: {e}"


def step_play(w, kind):
    """Three frames played forward or backward (sometimes half a frame on), mostly from a
    frame of the baked range: while a baked shot is used, nothing the add-on hides is
    seen at any of them."""
    import bpy
    scene = bpy.context.scene
    start, way = scene.frame_current, w.rng.choice((1, -1))
    b = scene.occ_bake if addon_enabled() else None
    if b is not None and b.hidden and w.rng.random() < 0.7:
        start = w.rng.randint(b.frame_start, b.frame_end)
    shown = []
    for k in range(1, 4):
        f = min(max(start + way * k, FRAMES[0]), FRAMES[1])
        sub = 0.5 if w.rng.random() < 0.3 and f < FRAMES[1] else 0.0
        scene.frame_set(f, subframe=sub)
        bpy.context.view_layer.update()
        shown.append(f + sub)
        if bake_on() and k < 3:                # the last frame: the step's own check
            w.stats["bake_checks"] += 1
            w.pending += check_cull(w)
    return f"play {shown}"


def step_bake_render(w, kind):
    """Apply to Render switched (the bake's sets written as hide_render keys, or removed);
    where none stand, mostly after a fresh bake (a workflow's bake goes stale within a few
    steps, and the keys' removal is what the steps after this one check)."""
    import bpy
    scene = bpy.context.scene
    fresh = ""
    try:
        if not scene.occ_bake.render_keys and w.rng.random() < 0.7:
            fresh = fresh_bake(w)
        r = sorted(bpy.ops.occ.bake_render())
    except RuntimeError as e:                  # no bake, stale, or refused: an ERROR report
        if "failed" in str(e):
            raise
        r = f"report: {e}"
    return f"apply to render -> {fresh}{r}, keys: {bool(bpy.context.scene.occ_bake.render_keys)}"


def add_behind_wall(w):
    """A small static box added right behind the wall a ray from the camera hits, near the
    middle of the frame (the workflow scene's occluded objects are mostly dynamic, which a
    bake never hides); -> what it did."""
    import bpy
    from mathutils import Vector
    scene = bpy.context.scene
    cam = scene.camera
    if cam is None or cam.type != "CAMERA" or "Walls" not in bpy.data.collections:
        return ""
    walls = set(bpy.data.collections["Walls"].all_objects)
    dg = bpy.context.evaluated_depsgraph_get()
    m = cam.matrix_world.normalized()
    corners = [m @ c for c in cam.data.view_frame(scene=scene)]    # top right, bottom right, bottom left, top left
    eye = m.translation
    for _ in range(12):
        u, v = w.rng.uniform(0.3, 0.7), w.rng.uniform(0.3, 0.7)
        top = corners[3].lerp(corners[0], u)
        bottom = corners[2].lerp(corners[1], u)
        way = (bottom.lerp(top, v) - eye).normalized() if cam.data.type != "ORTHO" else \
            (m.to_3x3() @ Vector((0, 0, -1))).normalized()
        start = eye if cam.data.type != "ORTHO" else bottom.lerp(top, v)
        hit, at, _, _, obj, _ = scene.ray_cast(dg, start, way)
        if hit and obj is not None and obj.original in walls and (at - start).length > 1.0:
            p = at + way * w.rng.uniform(0.5, 0.8)
            # (in the scene's own collection: an object another scene links gets no render keys)
            o = add_box(w, "Behind", tuple(p), (0.12, 0.12, 0.12), scene.collection, w.rng.uniform(0, 3))
            w.model["objects"][o["wf_id"]] = object_intent(o)
            return f"'{o.name}' added behind '{obj.original.name}', "
    return ""


def fresh_bake(w, behind=False):
    """Bake Shot over ten frames from a random one, the render's other view layers off
    first where several render (as Apply to Render asks); ``behind``: a box added behind
    a wall the camera sees at the first of them (:func:`add_behind_wall`); -> what it did."""
    import bpy
    scene = bpy.context.scene
    said = ""
    if sum(v.use for v in scene.view_layers) > 1 and not scene.render.use_single_layer:
        scene.render.use_single_layer = True
        said = "single layer, "
    a = w.rng.randint(FRAMES[0], FRAMES[1] - 9)
    if behind:
        scene.frame_set(a)                     # (the camera may be keyed)
        said += add_behind_wall(w)
    return said + f"baked {a}-{a + 9} {bake_shot(w, a, a + 9)}, "


def bake_shot(w, a, b):
    """``occ.bake_shot`` over frames ``a .. b``; a bake is an undo step of its own (the
    operator pushes one where an undo history exists): so is the model's."""
    import bpy
    r = sorted(bpy.ops.occ.bake_shot(frame_start=a, frame_end=b))
    if r == ["FINISHED"] and bpy.ops.ed.undo_history.poll():
        mirror_undo_push(w)
    return r


def step_render(w, kind):
    """A frame of the baked range as the final render takes it (sometimes half a frame on,
    a motion-blur sample): what the render hides there, by the render keys standing
    (Apply to Render) or by Render Baked Shot's set (where that renders with the bake), is
    nothing the camera sees (the truth at the render size, the add-on's hides undone).
    Pixels are not rendered here (EEVEE takes 30-60 s a frame at 160x90 on llvmpipe); the
    in-Blender checks ``render_keys_workflow`` and ``render_baked_shot`` compare renders
    pixel for pixel."""
    import bpy
    import numpy as np
    scene, context = bpy.context.scene, bpy.context
    bake = sys.modules[f"{ADDON_MODULE}.occ_addon.bake"]
    keys = sys.modules[f"{ADDON_MODULE}.occ_addon.render_keys"]
    b = scene.occ_bake
    baked = bake.stored(scene)
    fresh = ""
    if (baked is None or bake.STATE.status(context, baked) is not None) and w.rng.random() < 0.7:
        try:                                   # mostly a fresh bake (a workflow's goes stale soon) ...
            fresh = fresh_bake(w, behind=w.rng.random() < 0.8)
            if w.rng.random() < 0.5:           # ... half of them applied to the render
                fresh += f"applied {sorted(bpy.ops.occ.bake_render())}, "
        except RuntimeError as e:              # refused: an ERROR report, fine unless it is our bug
            if "failed" in str(e):
                raise
            fresh += f"report: {e}, "
    if not b.hidden:
        return f"render: {fresh}no bake"
    f = w.rng.randint(b.frame_start, b.frame_end)
    sub = 0.5 if w.rng.random() < 0.3 and f < b.frame_end else 0.0
    scene.frame_set(f, subframe=sub)
    context.view_layer.update()
    baked = bake.stored(scene)
    if baked is None:
        return f"render frame {f + sub}: {fresh}no bake decoded"
    items = bpy.data.objects.values()
    ids = bake.numbers()
    hidden, how = set(), "whole"
    if b.render_keys:
        hidden = {o.name for o in keys.keyed_objects() if o.hide_render and scene.objects.get(o.name) is not None}
        how = "keys"
    elif bake.STATE.status(context, baked) is None and bake.render_reason(context, baked) is None:
        try:
            camera, _ = bake.scene_camera(context)
        except Exception:                      # (no camera: the frame renders whole)
            camera = None
        if bake._camera_holds(baked, f, scene.frame_current_final, camera):
            take = bake.frame_mask(baked.frame(f), ids) & ~np.array([o.hide_render for o in items], dtype=bool)
            hidden = {items[i].name for i in np.flatnonzero(take).tolist()}
            how = "render baked shot"
    said = f"render {fresh}frame {f + sub}: {how}, {len(hidden)} hidden"
    if not hidden:
        return said
    # The truth is the viewport's (what it draws, the add-on's hides undone): it stands for
    # the render where every object the bake culled against is drawn there too (an occluder
    # hidden in the viewport since the bake still renders, and occludes there).
    held = [items[i] for i in np.flatnonzero(bake.usable(ids) & (ids < len(baked.held))).tolist()
            if baked.held[ids[i]]]
    if not all(o.visible_get() or hidden_by_addon(o) for o in held):
        return said + " (an occluder not drawn in the viewport: no truth)"
    seen, _ = truth_visible(w)
    if seen is not None:
        w.stats["render_checks"] += 1
        wrong = sorted(hidden & set(seen))
        if wrong:
            w.pending.append(f"r: the render at frame {f + sub} hides {wrong[:5]}, which the camera sees ({how})")
    return said


def check_render_keys():
    """Render keys stand only where they hold: the bake holds, its camera path and settings
    are the keyed ones and the render draws everything it culled against (the add-on's
    check, asked in full after every step: an edit of any kind that left them standing
    stale would show here); no key of the add-on's stands without a scene that applied it."""
    import bpy
    keys = sys.modules[f"{ADDON_MODULE}.occ_addon.render_keys"]
    context = bpy.context
    applied = [s.name for s in bpy.data.scenes if s.occ_bake.render_keys]
    keyed = keys.keyed_objects()
    if keyed and not applied:
        return [f"k: render keys left on {sorted(o.name for o in keyed)[:5]} with no scene applying them"]
    if context.scene.occ_bake.render_keys:
        why = keys.holds(context)
        if why is not None:
            return [f"k: render keys stand where they no longer hold: {why}"]
    return []


def bake_on():
    """Whether what the add-on hides now is a baked frame's set (Use Baked Shot on, no pass since)."""
    import bpy
    return addon_enabled() and bool(bpy.context.scene.occ_bake.use) \
        and sys.modules[f"{ADDON_MODULE}.occ_addon.bake"].STATE.owns()


SCENE_STEPS = {
    "cull": step_cull, "bake": step_bake, "bake_use": step_bake_use, "play": step_play,
    "bake_render": step_bake_render, "render": step_render,
    "restore": step_restore, "bad_value": lambda w, kind: do_bad_value(w),
    "live": step_live, "analyze": lambda w, kind: do_analyze(w), "camera_move": step_camera_move,
    "camera_nudge": step_camera_nudge, "camera_scale": step_camera_scale, "camera_lens": step_camera_lens,
    "frame": step_frame, "view_layer": step_view_layer, "add": step_add, "settings": step_settings,
    "exclude_setting": step_exclude_setting, "coll_eye": step_layer_collection,
    "coll_exclude": step_layer_collection, "coll_monitor": step_collection_monitor,
    "instance_move": step_instance_move, "scene_switch": step_scene_switch, "emitter_undo": step_emitter_undo,
    "revert": lambda w, kind: do_revert(w), "nv_add": step_nv_add, "nv_duplicate": step_nv_duplicate,
}
OBJECT_STEPS = {
    "object_move": step_object_move, "hide_eye": step_hide_eye, "hide_monitor": step_hide_monitor,
    "object_scale": step_object_scale, "mesh_edit": step_mesh_edit, "display_type": step_display_type,
    "never_cull": step_never_cull, "delete": step_delete, "rename": step_rename,
    "rename_swap": step_rename_swap, "rename_replace": step_rename_replace, "duplicate": step_copy,
    "link": step_copy, "move_collection": step_move_collection, "nv_move": step_nv_move,
}


def do_step(w, kind):
    """Apply one user action (a step of :data:`SCENE_STEPS` or :data:`OBJECT_STEPS`);
    returns a short description for the history."""
    if kind in SCENE_STEPS:
        return SCENE_STEPS[kind](w, kind)
    o = pick(w, animated=False if kind == "object_move" else None)    # prefers what the add-on hid
    if o is None:
        return f"{kind}: no object"
    return OBJECT_STEPS[kind](w, kind, o)


def live_module():
    return sys.modules.get(ADDON_MODULE + ".occ_addon.live")


def live_on():
    import bpy
    return addon_enabled() and bool(bpy.context.scene.occ.live)


def drive_live():
    """What the live timer would do after a step, with the debounce off: a few ticks
    (a timer function returning None is unregistered by Blender's timer loop)."""
    import bpy
    live = live_module()
    live.DEBOUNCE_S = 0.0
    for _ in range(LIVE_TICKS):
        if live._tick() is None:
            if bpy.app.timers.is_registered(live._tick):
                bpy.app.timers.unregister(live._tick)
            break
        live.settle()                 # the pass begun lands as the next tick would


def check_live_state():
    """The panel's live flag and the timer agree (the flag is the truth the user sees)."""
    import bpy
    live = live_module()
    flag = bool(bpy.context.scene.occ.live)
    timer = bpy.app.timers.is_registered(live._tick)
    if flag != timer:
        return [f"f: live shows {'on' if flag else 'off'} but its timer is "
                f"{'registered' if timer else 'not registered'}"]
    return []


def do_analyze(w, collect=None):
    """occ.analyze over three frames: each frame's report names every object the truth
    sees then, and the scene is left as it was.  ``collect``: "Collect Never Visible"
    (None: drawn at random)."""
    import bpy
    scene = bpy.context.scene
    first = w.rng.randint(FRAMES[0], FRAMES[1] - 2)
    frame = scene.frame_current
    path = os.path.join(w.work, f"wf_{w.seed}_analyze.json")
    drawn = w.rng.random() < 0.5                    # "Collect Never Visible" ticked
    collect = drawn if collect is None else collect
    # the truth of the scene as it is before the operator ("Collect Never Visible"
    # relinks objects: the scene after it may differ)
    truths = {}
    for f in range(first, first + 3):
        scene.frame_set(f)
        seen, _ = truth_visible(w)
        truths[f] = (seen or set(), {o.name for o in bpy.context.view_layer.objects if o.visible_get()})
    scene.frame_set(frame)
    before = homes()
    try:
        r = bpy.ops.occ.analyze(filepath=path, frame_start=first, frame_end=first + 2,
                                link_never_visible=collect)
    except RuntimeError as e:
        if "failed" in str(e):
            raise
        return f"analyze {first}..{first + 2} -> report: {e}"
    finally:
        w.pending += check_homes(before, "analyze" + (" collecting never visible" if collect else ""))
    problems = []
    if scene.frame_current != frame:
        problems.append(f"analyze: the frame is {scene.frame_current}, was {frame}")
    with open(path, encoding="utf-8") as f:
        report = json.load(f)
    seen_any = set()
    for entry in report["frames"]:
        seen, in_layer = truths[entry["frame"]]       # in_layer: what the report can name
        seen_any |= seen
        missing = sorted((seen & in_layer) - set(entry["visible"]))
        if missing:
            objs = bpy.data.objects
            why = {n: (f"display {objs[n].display_type}, never cull {objs[n].occ_never_cull}, "
                       f"eye {objs[n].hide_get()}, monitor {objs[n].hide_viewport}, "
                       f"add-on record {addon_hidden(objs[n])}, collections "
                       f"{[c.name for c in objs[n].users_collection]}") for n in missing}
            problems.append(f"analyze: frame {entry['frame']} leaves out visible {why}; exclude setting "
                            f"{scene.occ.exclude_collection and scene.occ.exclude_collection.name}")
    never = bpy.data.collections.get("Never Visible")
    if collect and never is not None:               # deleting its contents must never delete what is seen
        # (what the add-on linked there: what the user put there is the user's, seen or not)
        wrong = sorted(o.name for o in never.objects if o.name in seen_any and getattr(o, "occ_collected", True))
        if wrong:
            problems.append(f"analyze: 'Never Visible' holds objects seen in frames {first}..{first + 2}: {wrong}")
    w.pending += problems
    if collect and "FINISHED" in r:
        # Blender's consequence of the objects unlinked from the collection: one whose
        # other collections are all excluded loses its base there, and its eye flag
        # with it (the flag lived only through the collection: without it, excluding
        # its own collection had dropped the base already)
        forget_lost_bases(w)
        # the add-on excludes its collection in every view layer (it adds no way into one)
        for vl in bpy.context.scene.view_layers:
            for path, lc in layer_collections(vl):
                if lc.collection.name == "Never Visible":
                    w.model["lc"][(vl.name, path)] = [lc.hide_viewport, True]
        # the add-on makes the collection an undo step of its own (the history is never empty here)
        mirror_undo_push(w)
    return f"analyze {first}..{first + 2}{' collecting never visible' if collect else ''} -> {sorted(r)}"


def homes():
    """``{identity: (name, in a collection and used)}`` of every object in ``bpy.data``."""
    import bpy
    return {getattr(o, "session_uid", 0) or o.as_pointer(): (o.name, len(o.users_collection) > 0 and o.users > 0)
            for o in bpy.data.objects}


def check_homes(before, operation):
    """(h): nothing the add-on's ``operation`` did left an object in no collection, or
    took one out of ``bpy.data.objects`` (``before``: :func:`homes` before it)."""
    import bpy
    after = homes()
    problems = []
    gone = sorted(name for k, (name, _) in before.items() if k not in after)
    if gone:
        problems.append(f"h: {operation} removed objects from bpy.data.objects: {gone}")
    lost = sorted(after[k][0] for k, (_, home) in before.items() if home and k in after and not after[k][1])
    if lost:
        objs = bpy.data.objects
        problems.append(f"h: {operation} left objects in no collection (or unused): "
                        + ", ".join(f"'{n}' (users {objs[n].users}, occ_collected "
                                    f"{getattr(objs[n], 'occ_collected', None)})" for n in lost))
    return problems


def has_nan(o):
    """A NaN or infinity in the object's own transform or mesh (what the user sees in its data)."""
    import numpy as np
    if not np.all(np.isfinite([*o.location, *o.rotation_euler, *o.scale])):
        return True
    if o.type == "MESH" and o.data is not None and len(o.data.vertices):
        co = np.empty(3 * len(o.data.vertices), dtype=np.float32)
        o.data.vertices.foreach_get("co", co)
        return not np.all(np.isfinite(co))
    return False


def do_bad_value(w):
    """A NaN in one object's vertices or location (an import gone wrong), or the fix of it."""
    import bpy
    scene = bpy.context.scene
    broken = [o for o in scene.objects if "wf_bad" in o]
    if broken:
        o = broken[0]
        kind, old = o["wf_bad"][0], list(o["wf_bad"][1:])
        if kind == 0 and o.data is not None and len(o.data.vertices):
            o.data.vertices[0].co = old
            o.data.update()
        else:
            o.location = old
        del o["wf_bad"]
        return f"fix NaN of '{o.name}'"
    objs = [o for o in scene.objects if "wf_id" in o and o.type == "MESH" and o.data.users == 1
            and o.animation_data is None and o.parent is None]
    if not objs:
        return "bad value: no object"
    o = w.rng.choice(objs)
    if w.rng.random() < 0.5:
        o["wf_bad"] = [0, *o.data.vertices[0].co]
        o.data.vertices[0].co = (math.nan, 0.0, 0.0)
        o.data.update()
        return f"NaN in a vertex of '{o.name}'"
    o["wf_bad"] = [1, *o.location]
    o.location = (math.nan, 0.0, 0.0)
    return f"NaN in the location of '{o.name}'"


def do_undo(w, kind):
    import bpy
    if kind == "undo":
        if w.undo_pos < 1:
            return "undo: nothing to undo"
        bpy.ops.ed.undo()
        w.undo_pos -= 1
    else:
        if w.undo_pos >= len(w.undo) - 1:
            return "redo: nothing to redo"
        bpy.ops.ed.redo()
        w.undo_pos += 1
    w.model = copy.deepcopy(w.undo[w.undo_pos])
    return f"{kind} -> step {w.undo_pos}"


def do_save_reload(w):
    import bpy
    path = os.path.join(w.work, f"wf_{w.seed}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    how = w.rng.choice(["plain", "disabled", "enable_after"] if addon_on(w) else ["plain"])
    if w.plain:                                  # the add-on as it would be after the step
        w.plain_on = w.plain_on and how != "disabled"
    elif how != "plain":
        bpy.ops.preferences.addon_disable(module=ADDON_MODULE)
    bpy.ops.wm.open_mainfile(filepath=path)
    if how == "enable_after" and not w.plain:
        bpy.ops.preferences.addon_enable(module=ADDON_MODULE)
    w.saved = (path, copy.deepcopy(w.model))
    # loading starts a new undo history whose first step Blender does not undo to
    w.undo, w.undo_pos = [], -1
    push_undo(w, "reload")
    return f"save and reload ({how})"


def do_revert(w):
    """File > Revert: the file saved last (saved now, or by an earlier step), after a
    few edits since the save that the revert throws away."""
    import bpy
    rng = w.rng
    path = os.path.join(w.work, f"wf_{w.seed}.blend")
    what = []
    if w.saved is None or w.saved[0] != bpy.data.filepath or rng.random() < 0.6:
        bpy.ops.wm.save_as_mainfile(filepath=path)
        w.saved = (path, copy.deepcopy(w.model))
        what.append("save")
    for _ in range(rng.randint(0, 2)):             # edits after the save (lost by the revert)
        o = pick(w, hidden_first=0.3)
        if o is None:
            break
        if rng.random() < 0.5:
            o.location.x += rng.uniform(-2, 2)
            what.append(f"move '{o.name}'")
        else:
            step_move_collection(w, "move_collection", o)
            what.append(f"relink '{o.name}'")
        push_undo(w, "edit")
    bpy.ops.wm.revert_mainfile()
    w.model = copy.deepcopy(w.saved[1])
    w.undo, w.undo_pos = [], -1
    push_undo(w, "revert")
    return ", ".join(what + ["revert"])


def do_addon_toggle(w):
    import bpy
    if addon_enabled():
        bpy.ops.preferences.addon_disable(module=ADDON_MODULE)
        return "add-on disabled"
    bpy.ops.preferences.addon_enable(module=ADDON_MODULE)
    bpy.context.scene.occ.source = "CAMERA"     # settings, not hides: not in the model
    bpy.context.scene.occ.hide_in = HIDE_IN["mode"]
    return "add-on enabled"


def plain_truth(w, kind):
    """--plain: what the harness itself does with Blender in a cull or an analyze step of
    the add-on's run (its truth: the evaluated depsgraph's instances, its frame changes),
    without the add-on."""
    import bpy
    if not w.plain_on or kind not in ("cull", "analyze"):
        return ""
    if kind == "cull":
        truth_visible(w)
        return ", the truth drawn"
    scene = bpy.context.scene
    first, frame = w.rng.randint(FRAMES[0], FRAMES[1] - 2), scene.frame_current
    for f in range(first, first + 3):
        scene.frame_set(f)
        truth_visible(w)
    scene.frame_set(frame)
    return f", the truth drawn in frames {first}..{first + 2}"


def addon_on(w):
    """Whether the add-on is enabled (--plain: would be, in the run this one replays)."""
    return w.plain_on if w.plain else addon_enabled()


def choose(w):
    kinds = dict(w.kinds)
    if not addon_on(w) and not w.validate:
        undoes = {"undo", "redo", "emitter_undo"}
        for k in NEEDS_ADDON | (undoes if "undo_while_disabled" in KNOWN_UNFIXED else set()):
            kinds.pop(k, None)
        if "addon_toggle" in kinds:
            kinds["addon_toggle"] *= 8               # users turn it back on soon
    names = sorted(k for k in kinds if kinds[k])
    kind = w.choices.choices(names, weights=[kinds[k] for k in names])[0]
    stand_in = w.bake_choices.random() < BAKE_SHARE
    baked = sorted(w.bake_kinds) if addon_on(w) else []
    pick = w.bake_choices.choices(baked, weights=[w.bake_kinds[k] for k in baked])[0] if baked else None
    return pick if stand_in and pick is not None else kind


class Tee(io.TextIOBase):
    """stderr that is also kept: a traceback printed by anything is a failure."""

    def __init__(self, real):
        self.real, self.buf = real, io.StringIO()

    def write(self, s):
        self.buf.write(s)
        return self.real.write(s)

    def flush(self):
        self.real.flush()


def run_seed(w, steps, verbose=False, progress=None):
    """``progress``: a file each step is written to (flushed) before it runs: what a crash leaves."""
    import bpy
    if progress:
        progress.write(f"{w.seed} 0 build\n")
        progress.flush()
    build_scene(w)
    for step in range(1, steps + 1):
        kind = choose(w)
        # each step draws from its own generator: the step kinds of a seed do not depend
        # on what a step drew (--plain replays the same kinds without the add-on)
        w.rng = random.Random(f"{w.seed}:{step}")
        what = kind
        tee = Tee(sys.stderr)
        problems = []
        if progress:
            progress.write(f"{w.seed} {step} {kind}\n")
            progress.flush()
        with contextlib.redirect_stderr(tee):
            try:
                before = homes() if kind in ADDON_OPS else None
                if step in w.drop:
                    what = f"{kind} (dropped)"
                elif w.plain and kind in NEEDS_ADDON | PLAIN_SKIPS:
                    if kind == "addon_toggle":
                        w.plain_on = not w.plain_on
                    what = f"{kind} (skipped: --plain)" + plain_truth(w, kind)
                elif kind in ("undo", "redo"):
                    what = do_undo(w, kind)
                elif kind == "save_reload":
                    what = do_save_reload(w)
                elif kind == "addon_toggle":
                    what = do_addon_toggle(w)
                elif kind == "revert":
                    what = do_revert(w)
                else:
                    what = do_step(w, kind)
                if before is not None:
                    problems += check_homes(before, kind.replace("_", " "))
                if kind not in NO_PUSH:
                    push_undo(w, kind)
                bpy.context.view_layer.update()
                if addon_enabled() and live_module().WATCH.leaving:
                    live_module()._leave_timer()                 # the window's timer, before a redraw
                problems += w.pending
                w.pending = []
                live = live_on()
                if live and kind == "camera_nudge":
                    # before the live timer runs again: the hidden set on screen holds for
                    # the moved camera, or was shown when the camera left its envelope
                    problems += check_cull(w)
                if live:
                    before = homes()
                    drive_live()
                    problems += check_homes(before, "a live pass")
                if addon_enabled():
                    problems += check_live_state()
                    sys.modules[f"{ADDON_MODULE}.occ_addon.render_keys"].poll()   # the window's timer
                    problems += check_render_keys()
                problems += check_state(w, after_restore=kind == "restore" or not addon_enabled())
                baked = bake_on()
                w.stats["bake_checks"] += baked
                if (kind == "cull" and what.startswith("cull -> ['FINISHED']")) or (live and live_on()) or baked \
                        or (addon_enabled() and any(hidden_by_addon(o) for o in bpy.context.scene.objects)):
                    # every set on screen, after whatever step: a click's too, after an edit
                    problems += check_cull(w)
                elif w.validate and kind.startswith("camera"):
                    problems += check_truth_camera(w)
            except Exception:
                problems.append("d: exception: " + traceback.format_exc())
        if "Traceback" in tee.buf.getvalue():
            problems.append("d: traceback printed: " + tee.buf.getvalue()[-2000:])
        w.counts[kind] = w.counts.get(kind, 0) + 1
        w.history.append(f"{step}: {w.note}{what}")
        w.note = ""
        if verbose:
            print(f"[seed {w.seed}] {step}: {what}", flush=True)
        if problems:
            return {"step": step, "kind": kind, "problems": problems,
                    "history": w.history[-w.tail:]}
    return None


def main():
    args = parse_args()
    if not args.zip and not (args.validate or args.plain):
        bootstrap(args)
    sys.path.insert(0, ROOT)                     # the repository's core: the truth, apart from the add-on's copy
    from concurrent.futures import ThreadPoolExecutor

    import bpy
    seeds = list(args.seed or []) + [int(s) for s in (args.seeds or "").split(",") if s]
    seeds = seeds or [1]
    HIDE_IN["mode"] = args.hide_in
    GROUND["half"] = args.ground
    work = args.work or tempfile.mkdtemp(prefix="occ_workflows_")
    skip = {s for s in args.skip.split(",") if s}
    if bpy.app.version < (5, 0, 0):
        KNOWN_UNFIXED["emitter_undo"] = (
            "Blender 4.2 crashes on its own after an emitter's delete and undo with a second view layer "
            "shown, whatever else happens (tools/repro/blender42_hair_undo_crash.py, no add-on: 3 of 3 runs); "
            "the step kind runs on Blender 5.x only")
    out = {"seeds": {}, "not_exercised": NOT_EXERCISED, "known_unfixed": KNOWN_UNFIXED}
    if not (args.validate or args.plain):
        bpy.ops.extensions.package_install_files(filepath=args.zip, repo="user_default", enable_on_install=True)
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="wf-truth")
    progress = open(args.progress, "a", encoding="utf-8") if args.progress else None     # noqa: SIM115
    faulthandler.enable()                        # a crash prints the Python stack of its step
    for seed in seeds:
        w = World(seed, work, args.validate, skip, args.plain)
        w.truth_pool, w.tail = pool, args.tail
        w.drop = {int(s) for s in args.drop.split(",") if s}
        t = time.perf_counter()
        if not (args.validate or args.plain) and not addon_enabled():
            bpy.ops.preferences.addon_enable(module=ADDON_MODULE)
        try:
            failure = run_seed(w, args.steps, args.verbose, progress)
        except Exception:
            failure = {"step": len(w.history), "kind": "harness", "problems": [traceback.format_exc()],
                       "history": w.history[-w.tail:]}
        out["kinds"] = sorted({**w.kinds, **w.bake_kinds})
        out["seeds"][str(seed)] = {"failure": failure, "steps": len(w.history), "counts": w.counts, "stats": w.stats,
                                   "seconds": round(time.perf_counter() - t, 2)}
        if failure:
            print(f"seed {seed} FAILED at step {failure['step']} ({failure['kind']}):\n  "
                  + "\n  ".join(failure["problems"]) + "\n  history:\n    " + "\n    ".join(failure["history"]),
                  file=sys.stderr, flush=True)
    if "ctx" in _GL:
        pool.submit(_GL["ctx"].release).result()
    pool.shutdown()
    if progress:
        progress.write("end\n")
        progress.close()
    print("OCC_WORKFLOWS_END", file=sys.stderr, flush=True)    # what follows is the exit's
    print("OCC_WORKFLOWS " + json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
