"""Scale scenes in real Blender (bpy from PyPI) and in the engine alone, timed phase by phase.

    .venv/bin/python tools/bench/blender_scale.py [--quick] [--objects N] [--vertices V] [--only S,..]
    .venv/bin/python tools/bench/blender_scale.py engine [--vertices V] [--profile OUT] [--numpy]

Blender mode builds the add-on's zip (``tools/build_extension.py --no-wheels``),
installs it into an isolated ``BLENDER_USER_RESOURCES`` (as the Blender tests
do) and builds, each in a fresh file, the scenes of the scale issue:

- ``shared``: N objects (default 50,000) sharing one cube mesh, in rows behind a long wall;
- ``unique``: the same with one mesh per object;
- ``grid``: one grid mesh of V vertices (default 10 million), partly behind a wall;
- ``analyze``: ``occ.analyze`` over F frames (default 200) of a 3,000-object scene.

and times, from the scene camera (with the add-on's ``--hide-in`` setting; each
pass's note splits Blender's own updates from the add-on's work): the first ``occ.cull`` (extraction, build,
pass, hiding), the passes after small turns of the camera to and fro (median of
``--turns`` for each of ``--turn-rad``), ``occ.restore`` and Blender's update
after it, a Cull click after a switch to a new view layer, analyze, and memory: resident set before the
add-on ran (the scene's own), the peak above it (``VmHWM``, reset before each
scene with ``/proc/self/clear_refs``) and what stays after.  ``--profile DIR``
writes a cProfile of each phase.

Engine mode is the same grid without Blender: a ``core.Scene`` of one grid
mesh, timed through ``make_units`` (chunking), the hierarchy, the GL upload
and the first pass, with the peak memory of each phase above the scene's own
arrays; ``--numpy`` adds each phase's peak of traced allocations (numpy's
arrays, through ``tracemalloc``), which the allocator's caching of freed memory
does not blur.

``--envelope`` makes each Cull click's pass the envelope pass at rest of a click from a 3D
view (the scene's Live setting on).
"""

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
import tracemalloc

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXT_ID = "occlusion_culled_viewport"
MB = 2**20


# --- memory -------------------------------------------------------------------
def memory():
    """(resident, peak resident) of this process in bytes (Linux /proc)."""
    d = {}
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(("VmRSS", "VmHWM")):
                key, val = line.split(":")
                d[key] = int(val.split()[0]) * 1024
    return d.get("VmRSS", 0), d.get("VmHWM", 0)


def reset_peak():
    """Peak resident set := current (Linux >= 4.0); False where not allowed."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


ENGINE_PROFILE = {"profile": None}       # the engine thread's profile of the phase running now
TRACED_BASE = {"bytes": 0}               # traced bytes when tracing started (engine mode --numpy)
PEAK_SEEN = {"bytes": 0}                 # the highest VmHWM read before a step reset it (see Step)


class Phase:
    """Times a block and records its peak resident set above ``base`` bytes (and,
    while ``tracemalloc`` traces, the peak of traced allocations -- numpy's
    included -- above those held when it started, which no allocator's caching
    blurs); with a profile folder, writes ``<name>.prof`` (this thread) and
    ``<name>.engine.prof`` (the add-on's engine thread, see :func:`profile_engine_thread`)."""

    def __init__(self, table, name, base, profile_dir=None):
        self.table, self.name, self.base, self.profile_dir = table, name, base, profile_dir

    def __enter__(self):
        reset_peak()
        PEAK_SEEN["bytes"] = 0
        if tracemalloc.is_tracing():
            self.traced = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
        self.prof = cProfile.Profile() if self.profile_dir else None
        ENGINE_PROFILE["profile"] = cProfile.Profile() if self.profile_dir else None
        if self.prof:
            self.prof.enable()
        self.t, self.cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        dt, cpu = time.perf_counter() - self.t, time.process_time() - self.cpu
        if self.prof:
            self.prof.disable()
            path = os.path.join(self.profile_dir, f"{self.name}.prof")
            self.prof.dump_stats(path)
            engine = ENGINE_PROFILE["profile"]
            if engine is not None and engine.getstats():
                engine.dump_stats(os.path.join(self.profile_dir, f"{self.name}.engine.prof"))
        ENGINE_PROFILE["profile"] = None
        rss, peak = memory()
        peak = max(peak, PEAK_SEEN["bytes"])          # steps inside reset the peak: theirs count
        row = {"phase": self.name, "seconds": dt, "cpu_seconds": cpu,
               "peak_above_MB": (peak - self.base) / MB, "after_above_MB": (rss - self.base) / MB}
        if tracemalloc.is_tracing():
            traced, traced_peak = tracemalloc.get_traced_memory()
            row["numpy_peak_MB"] = (traced_peak - TRACED_BASE["bytes"]) / MB
            row["numpy_after_MB"] = (traced - TRACED_BASE["bytes"]) / MB
        self.table.append(row)


class Step:
    """Wraps a function of the add-on (any thread): each call's time and peak
    resident set above ``base`` become a row of ``table`` named ``"  " + name``; the
    peak before the call is kept in ``PEAK_SEEN`` for the enclosing :class:`Phase`."""

    def __init__(self, table, name, base):
        self.table, self.name, self.base = table, name, base

    def _begin(self):
        PEAK_SEEN["bytes"] = max(PEAK_SEEN["bytes"], memory()[1])
        reset_peak()
        return time.perf_counter()

    def _end(self, t):
        rss, peak = memory()
        PEAK_SEEN["bytes"] = max(PEAK_SEEN["bytes"], peak)
        self.table.append({"phase": f"  {self.name}", "seconds": time.perf_counter() - t,
                           "peak_above_MB": (peak - self.base) / MB,
                           "after_above_MB": (rss - self.base) / MB})

    def wrap(self, fn):
        def call(*a, **k):
            t = self._begin()
            try:
                return fn(*a, **k)
            finally:
                self._end(t)
        return call

    def wrap_steps(self, fn):
        """The same for a generator of steps (the add-on's modal work): its whole run."""
        def call(*a, **k):
            t = self._begin()
            try:
                return (yield from fn(*a, **k))
            finally:
                self._end(t)
        return call


def step_addon(table, base):
    """The first cull's steps as rows: the add-on's extraction (candidates, scene
    arrays), the engine's build (chunking, hierarchy, GL upload) and pass, the
    never-hide policy and the hiding (its local-view entry apart).
    Returns a function that puts the add-on's own functions back."""
    import importlib
    extract, engine, gl, policy, visibility, localview = (
        importlib.import_module(f"bl_ext.user_default.{EXT_ID}.{m}")       # core.gl: lazily imported otherwise
        for m in ("occ_addon.extract", "core.engine", "core.gl", "occ_addon.policy", "occ_addon.visibility",
                  "occ_addon.localview"))
    steps = [(extract.Extractor, "candidates", "extract: candidates"),
             (extract.Extractor, "scene_steps", "extract: scene arrays"),
             (engine, "make_units", "engine: make_units (chunking)"),
             (engine, "build_hierarchy", "engine: build_hierarchy"),
             (gl, "GLRenderer", "engine: GLRenderer (upload)"),
             (engine.Culler, "cull", "engine: pass"),
             (policy, "never_hidden", "policy: never hidden"),
             (localview, "enter", "hide: entering the own local view"),
             (visibility, "apply", "hide: apply (entry included; the update after it not)")]
    originals = [(owner, attr, getattr(owner, attr)) for owner, attr, _ in steps]
    for owner, attr, name in steps:
        step = Step(table, name, base)
        setattr(owner, attr, (step.wrap_steps if attr.endswith("_steps") else step.wrap)(getattr(owner, attr)))

    def undo():
        for owner, attr, fn in originals:
            setattr(owner, attr, fn)
    return undo


def print_table(title, rows):
    traced = any("numpy_peak_MB" in r for r in rows)
    print(f"\n{title}")
    print(f"{'phase':<42}{'seconds':>9}{'CPU s':>8}{'peak above (MB)':>17}{'after (MB)':>12}"
          + (f"{'numpy peak':>12}{'numpy after':>13}" if traced else ""))
    for r in rows:
        extra = f"  {r['note']}" if r.get("note") else ""
        cpu = f"{r['cpu_seconds']:>8.2f}" if "cpu_seconds" in r else f"{'':>8}"
        if traced:
            cpu_extra = (f"{r['numpy_peak_MB']:>12.0f}{r['numpy_after_MB']:>13.0f}" if "numpy_peak_MB" in r
                         else f"{'':>25}")
        else:
            cpu_extra = ""
        print(f"{r['phase']:<42}{r['seconds']:>9.3f}{cpu}{r['peak_above_MB']:>17.0f}{r['after_above_MB']:>12.0f}"
              f"{cpu_extra}{extra}")


def print_profile(path, top=25):
    stats = pstats.Stats(path)
    stats.sort_stats("cumulative").print_stats(top)
    stats.sort_stats("tottime").print_stats(top)


# --- geometry -------------------------------------------------------------------
def grid_arrays(vertices, size=40.0, dtype=np.float64):
    """A square grid of about ``vertices`` vertices in the plane x = 0 (y, z in
    [-size/2, size/2]) with a gentle relief in x: ``(v, 3)`` vertices and
    ``(2 (n-1)^2, 3) int64`` triangles."""
    n = max(2, int(round(np.sqrt(vertices))))
    t = np.linspace(-size / 2, size / 2, n)
    v = np.empty((n * n, 3), dtype=dtype)
    v[:, 1] = np.tile(t, n)
    v[:, 2] = np.repeat(t, n)
    v[:, 0] = 0.3 * np.sin(v[:, 1] * 0.7) * np.cos(v[:, 2] * 0.5)
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()   # lower-left corner of each quad
    f = np.empty((2 * len(q), 3), dtype=np.int64)
    f[0::2, 0], f[0::2, 1], f[0::2, 2] = q, q + 1, q + n + 1
    f[1::2, 0], f[1::2, 1], f[1::2, 2] = q, q + n + 1, q + n
    return v, f


# --- engine mode ------------------------------------------------------------------
def engine_main(args):
    sys.path.insert(0, ROOT)
    import core
    import core.engine as engine
    import core.gl as gl
    from core.camera import Camera

    rows = []
    t = time.perf_counter()
    v, f = grid_arrays(args.vertices)
    v, f = v.astype(np.float32), f.astype(np.int32)  # as the add-on reads them from Blender (Scene keeps them)
    wall_v = np.array([[-5, -30, -30], [-5, 0, -30], [-5, 0, 30], [-5, -30, 30]], dtype=np.float64)
    wall_f = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    eye = np.eye(4)
    scene = core.Scene.from_arrays(["grid", "wall"], [(v, f), (wall_v, wall_f)], [0, 1], [eye, eye])
    own = sum(a.nbytes for mesh in scene.meshes for a in mesh)
    make_s = time.perf_counter() - t
    rss, _ = memory()
    print(f"grid: {len(v):,} vertices, {len(f):,} triangles; scene arrays {own / MB:.0f} MB; "
          f"resident {rss / MB:.0f} MB (made in {make_s:.1f} s)")
    base = rss
    prof = args.profile

    def timed(name, fn):
        def wrapper(*a, **k):
            with Phase(rows, name, base, prof):
                return fn(*a, **k)
        return wrapper

    engine.make_units = timed("make_units (chunking)", engine.make_units)
    engine.build_hierarchy = timed("build_hierarchy", engine.build_hierarchy)
    gl.GLRenderer = timed("GLRenderer (upload)", gl.GLRenderer)
    cam = Camera.look_at([-30.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], fov_y_deg=60.0,
                         aspect=16 / 9, near=0.1, far=200.0)
    reset_peak()
    if args.numpy:
        tracemalloc.start()
        TRACED_BASE["bytes"] = tracemalloc.get_traced_memory()[0]
    t0, cpu0 = time.perf_counter(), time.process_time()
    culler = core.Culler(scene, (640, 360), chunk_triangles=args.chunk_triangles)
    with Phase(rows, "first pass", base, prof):
        res = culler.cull(cam)
    total, cpu_total = time.perf_counter() - t0, time.process_time() - cpu0
    _, peak = memory()          # the peak since the Culler started (each phase reset it)
    peaks = max(r["peak_above_MB"] for r in rows)
    numpy_peak = max((r["numpy_peak_MB"] for r in rows if "numpy_peak_MB" in r), default=None)
    if tracemalloc.is_tracing():
        tracemalloc.stop()                  # the turns below are timed untraced
    turn = []
    for k in range(args.turns):
        a = 0.01 * (k + 1)
        c = Camera.look_at([-30.0, 0.0, 0.0], [0.0, 30.0 * np.sin(a), 0.0], [0.0, 0.0, 1.0],
                           fov_y_deg=60.0, aspect=16 / 9, near=0.1, far=200.0)
        t1 = time.perf_counter()
        culler.cull(c)
        turn.append(time.perf_counter() - t1)
    truth = culler.truth(cam)
    missed = int((truth & ~res.visible).sum())
    rows.append({"phase": "first cull (all of the above)", "seconds": total, "cpu_seconds": cpu_total,
                 "peak_above_MB": peaks,
                 "after_above_MB": (memory()[0] - base) / MB,
                 **({"numpy_peak_MB": numpy_peak, "numpy_after_MB": rows[-1]["numpy_after_MB"]}
                    if numpy_peak is not None else {})})
    rows.append({"phase": f"pass after 0.01 rad turn (median {args.turns})", "seconds": float(np.median(turn)),
                 "peak_above_MB": float("nan"), "after_above_MB": (memory()[0] - base) / MB})
    print_table(f"engine, one grid mesh of {len(v):,} vertices / {len(f):,} triangles "
                f"(chunks of {args.chunk_triangles}): {len(culler.units)} units, "
                f"{res.stats.occluded} occluded; false negatives vs truth: {missed}", rows)
    print(f"scene's own arrays {own / MB:.0f} MB; resident before the engine {base / MB:.0f} MB; "
          f"structure {culler.structure_mb():.0f} MB")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"vertices": len(v), "triangles": len(f), "units": len(culler.units),
                       "scene_MB": own / MB, "false_negatives": missed, "rows": rows}, fh, indent=1)
    culler.close()
    if prof:
        for r in rows[:3]:
            p = os.path.join(prof, f"{r['phase']}.prof")
            if os.path.exists(p):
                print_profile(p, args.top)
    return 1 if missed else 0


# --- Blender mode: scenes ------------------------------------------------------------
def _cube_mesh(bpy, name):
    """A unit cube mesh (8 vertices, 6 quads) centred on the origin, in bulk."""
    me = bpy.data.meshes.new(name)
    v = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)], np.float32)
    quads = np.array([[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])
    _fill_mesh(me, v, quads)
    return me


def _fill_mesh(me, verts, polys):
    """Vertices ``(v, 3)`` and polygons ``(p, k)`` of one corner count into an empty mesh."""
    me.vertices.add(len(verts))
    me.vertices.foreach_set("co", np.ascontiguousarray(verts, dtype=np.float32).ravel())
    me.loops.add(polys.size)
    me.loops.foreach_set("vertex_index", np.ascontiguousarray(polys, dtype=np.int32).ravel())
    me.polygons.add(len(polys))
    k = polys.shape[1]
    me.polygons.foreach_set("loop_start", np.arange(0, polys.size, k, dtype=np.int32))
    me.update(calc_edges=True)


def _box_object(bpy, name, lo, hi):
    o = bpy.data.objects.new(name, _cube_mesh(bpy, name))
    bpy.context.scene.collection.objects.link(o)
    o.location = [(a + b) / 2 for a, b in zip(lo, hi, strict=True)]
    o.scale = [b - a for a, b in zip(lo, hi, strict=True)]
    return o


def _camera(bpy, location, rotation, clip_end):
    scene = bpy.context.scene
    data = bpy.data.cameras.new("cam")
    data.clip_end = clip_end
    cam = bpy.data.objects.new("cam", data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = location
    cam.rotation_euler = rotation
    return cam


LOOK_X = (np.pi / 2, 0.0, -np.pi / 2)       # a Blender camera looking down +X, Z up


def build_rows(bpy, n, unique):
    """``n`` unit cubes in rows behind a long wall (its ends leave the outer columns
    in view), the scene camera in front of the wall: most cubes occluded, some
    visible past the wall's ends, some outside the view."""
    cols = int(np.ceil(np.sqrt(2 * n)))
    width = 3.0 * cols
    shared = None if unique else _cube_mesh(bpy, "cube")
    coll = bpy.context.scene.collection
    i = np.arange(n)
    xs, ys = 2.0 + 3.0 * (i // cols), -width / 2 + 3.0 * (i % cols)
    for k in range(n):                      # building the scene, not timed
        o = bpy.data.objects.new(f"cube{k:06d}", shared if shared is not None else _cube_mesh(bpy, f"cube{k}"))
        o.location = (xs[k], ys[k], 0.5)
        coll.objects.link(o)
    _box_object(bpy, "wall", (0.0, -0.1 * width, -1.0), (0.5, 0.1 * width, 4.0))
    return _camera(bpy, (-0.6 * width, 0.0, 3.0), LOOK_X, 10.0 * width)


def build_grid(bpy, vertices):
    """One grid mesh of about ``vertices`` vertices (quads) in the plane x = 10, half
    of it behind a wall, the camera in front."""
    v, _ = grid_arrays(vertices, dtype=np.float32)
    n = int(round(np.sqrt(len(v))))
    v[:, 0] += 10.0
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    quads = np.stack([q, q + 1, q + n + 1, q + n], axis=1)
    me = bpy.data.meshes.new("grid")
    _fill_mesh(me, v, quads)
    del v, q, quads
    o = bpy.data.objects.new("grid", me)
    bpy.context.scene.collection.objects.link(o)
    _box_object(bpy, "wall", (-5.5, -30.0, -30.0), (-5.0, 0.0, 30.0))
    return _camera(bpy, (-30.0, 0.0, 0.0), LOOK_X, 200.0)


def build_path(bpy, n, frames):
    """The rows scene with ``n`` objects and the camera moving sideways over ``frames`` frames."""
    cam = build_rows(bpy, n, unique=False)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    y0 = cam.location.y
    width = -cam.location.x / 0.6
    for f, y in ((1, y0 - 0.3 * width), (frames, y0 + 0.3 * width)):
        cam.location.y = y
        cam.keyframe_insert("location", frame=f)
    return cam


# --- Blender mode: one scene in this process -------------------------------------------
def _addon(name):
    return sys.modules[f"bl_ext.user_default.{EXT_ID}.{name}"]


def profile_engine_thread():
    """Profile what the add-on runs on its engine thread (cProfile sees one thread)."""
    worker = _addon("occ_addon.worker").EngineThread
    run = worker.run

    def profiled(self, fn, *a, **k):
        def call(*a, **k):
            prof = ENGINE_PROFILE["profile"]
            if prof is None:
                return fn(*a, **k)
            prof.enable()
            try:
                return fn(*a, **k)
            finally:
                prof.disable()
        return run(self, call, *a, **k)

    worker.run = profiled


def engine_waits():
    """Count the main thread's time blocked on the engine thread (``Job.wait`` and
    ``Job.result`` of the add-on's worker) into the returned dict's ``"s"``."""
    job = _addon("occ_addon.worker").Job
    waited = {"s": 0.0}

    def timed(fn):
        def call(self):
            t = time.perf_counter()
            try:
                return fn(self)
            finally:
                waited["s"] += time.perf_counter() - t
        return call
    job.wait, job.result = timed(job.wait), timed(job.result)
    return waited


def _false_negatives(bpy):
    """Objects the add-on hid that the engine's object-ID truth of the same view shows."""
    try:
        session = _addon("occ_addon.session")
        sess = session.SESSION
        camera, _ = _addon("occ_addon.cameras").camera_for(bpy.context)
        truth = sess.worker.run(sess.culler.truth, camera)
        objs = bpy.data.objects
        flags = _addon("occ_addon.visibility").culled()    # either channel, one bulk read each
        ids = _addon("occ_addon.identity").uids(objs)     # the engine's objects by session id
        by_id = np.argsort(ids)
        hidden = flags[by_id[np.searchsorted(ids, sess.held.uids, sorter=by_id)]]
        return int((truth & hidden).sum()), int(hidden.sum())
    except Exception as e:  # the add-on's internals may change: say so, do not fail the timing
        print(f"false-negative check unavailable: {type(e).__name__}: {e}")
        return None, None


def child_main(args):
    import bpy

    rows = []
    bpy.ops.extensions.package_install_files(filepath=args.zip, repo="user_default", enable_on_install=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 1280, 720
    t = time.perf_counter()
    if args.scene in ("shared", "unique"):
        cam = build_rows(bpy, args.objects, unique=args.scene == "unique")
        label = f"{args.objects:,} objects, {'unique meshes' if args.scene == 'unique' else 'one shared mesh'}"
    elif args.scene == "grid":
        cam = build_grid(bpy, args.vertices)
        label = f"one grid mesh of {len(bpy.data.meshes['grid'].vertices):,} vertices"
    else:
        cam = build_path(bpy, args.analyze_objects, args.frames)
        label = f"analyze: {args.analyze_objects:,} objects, {args.frames} frames"
    bpy.context.view_layer.update()
    scene.occ.source = "CAMERA"
    scene.occ.hide_in = args.hide_in
    if args.strategy:
        scene.occ.strategy = args.strategy
    if args.envelope:
        scene.occ.live = True
    build_s = time.perf_counter() - t
    base, _ = memory()
    print(f"{label}: scene built in {build_s:.1f} s, resident {base / MB:.0f} MB", flush=True)
    prof = args.profile and os.path.join(args.profile, args.scene)
    if prof:
        os.makedirs(prof, exist_ok=True)
        profile_engine_thread()
    result = {"scene": args.scene, "label": label, "resident_scene_MB": base / MB}
    if args.scene == "analyze":
        out = os.path.join(tempfile.mkdtemp(prefix="occ_scale_"), "report.json")
        with Phase(rows, "analyze", base, prof):
            r = bpy.ops.occ.analyze(frame_start=1, frame_end=args.frames, filepath=out)
        rows[-1]["note"] = f"{r}"
    else:
        steps = []
        undo = step_addon(steps, base) if args.steps else None
        with Phase(rows, "first cull (extract, build, pass, hide)", base, prof):
            r = bpy.ops.occ.cull()
        cull_row = rows[-1]
        if undo is not None:              # the later passes are not stepped
            undo()
            rows += steps
        last = _addon("occ_addon.session").SESSION.last
        fn, hidden = _false_negatives(bpy)
        blender_s = last.blender_ms / 1e3
        cull_row["note"] = (f"{r}, {hidden} hidden, false negatives {fn}; Blender's updates "
                            f"{blender_s:.3f} s, add-on {cull_row['seconds'] - blender_s:.3f} s")
        result.update(false_negatives=fn, hidden=hidden, first_blender_s=last.blender_ms / 1e3)
        waited = engine_waits()
        for turn in args.turn_rad:
            times, cpus, blender, changed, waits = [], [], [], [], []
            peak_before = memory()[1]
            for k in range(args.turns):
                cam.rotation_euler.z += turn * (1 if k % 2 == 0 else -1)   # to and fro: objects come and go
                # the move is evaluated before the pass, as the user's own move is before a click
                bpy.context.view_layer.update()
                p = Phase([], f"turn{k}", base, prof if k == 0 else None)
                waited["s"] = 0.0
                with p:
                    bpy.ops.occ.cull()
                waits.append(waited["s"])
                last = _addon("occ_addon.session").SESSION.last
                times.append(p.table[-1]["seconds"])
                cpus.append(p.table[-1]["cpu_seconds"])
                blender.append(last.blender_ms / 1e3)
                changed.append(last.changed)
                fn_k, _ = _false_negatives(bpy)
                if fn_k:
                    result["false_negatives"] = (result["false_negatives"] or 0) + fn_k
            rss = memory()[0]
            med = float(np.median(times)) if times else float("nan")
            # the add-on's own part: the pass less Blender's updates and the main thread's
            # waits for the engine thread (its reads, policy and writes)
            own = float(np.median(np.array(times) - np.array(blender) - np.array(waits))) if times else float("nan")
            rows.append({"phase": f"pass after {turn:g} rad turn (median of {len(times)})",
                         "seconds": med, "cpu_seconds": float(np.median(cpus)) if cpus else float("nan"),
                         "peak_above_MB": (max(memory()[1], peak_before) - base) / MB,
                         "after_above_MB": (rss - base) / MB,
                         "note": f"max {max(times, default=0):.3f} s; Blender's updates median "
                                 f"{np.median(blender):.3f} s, add-on {med - np.median(blender):.3f} s "
                                 f"(waiting for the engine {np.median(waits):.3f} s, its own {own:.3f} s); "
                                 f"hiding changed {min(changed, default=0)}-{max(changed, default=0)} objects"})
            result[f"turn_{turn:g}"] = {"seconds": med, "blender_s": float(np.median(blender)),
                                        "engine_wait_s": float(np.median(waits)), "addon_own_s": own,
                                        "changed": changed}
        # a selection while the set stands: Blender's update, and in its handler the
        # add-on's check that a change of the scene alone leaves the set as it was made
        # (objects the set leaves drawn: selecting a hidden one gives the set back, by design)
        hid = _addon("occ_addon.visibility").culled()
        drawn_now = [o for o, h in zip(bpy.data.objects, hid.tolist(), strict=True) if not h and o.type == "MESH"]
        live, picked, checks = _addon("occ_addon.live"), drawn_now[:5], []
        with Phase(rows, "5 selections while the set stands", base, prof):
            for k, o in enumerate(picked):
                o.select_set(k % 2 == 0)
                bpy.context.view_layer.update()
        for _ in range(5):
            t = time.perf_counter()
            live._scene_holds(scene)
            checks.append(time.perf_counter() - t)
        rows[-1]["note"] = (f"the set stands: {not live.WATCH.leaving}; the add-on's check alone "
                            f"{1e3 * float(np.median(checks)):.1f} ms (median of 5)")
        with Phase(rows, "restore (the operator)", base, prof):
            bpy.ops.occ.restore()
        with Phase(rows, "restore: Blender's update after it", base, prof):
            bpy.context.view_layer.update()
        if bpy.context.window is not None:
            # another view layer: its first pass reads every geometry again (an edit made
            # while the object was in no evaluated layer is reported by none)
            bpy.context.window.view_layer = scene.view_layers.new("Switched")
            bpy.context.view_layer.update()           # the switch evaluated, as the user's own
            with Phase(rows, "cull after a switch to a new view layer", base, prof):
                r = bpy.ops.occ.cull()
            last = _addon("occ_addon.session").SESSION.last
            fn, hidden = _false_negatives(bpy)
            rows[-1]["note"] = (f"{r}, {hidden} hidden, false negatives {fn}; Blender's updates "
                                f"{last.blender_ms / 1e3:.3f} s")
            result["layer_switch_s"] = rows[-1]["seconds"]
            bpy.ops.occ.restore()
    result["rows"] = rows
    print_table(label, rows)
    print("SCALE_RESULT " + json.dumps(result), flush=True)
    # disabled here, while its engine thread is alive (at interpreter exit the add-on's
    # unregister finds that thread's pool shut down, seen in bpy 5.0.1)
    bpy.ops.preferences.addon_disable(module=f"bl_ext.user_default.{EXT_ID}")
    if prof and args.top:
        for name in sorted(os.listdir(prof)):
            print(f"\n=== profile {args.scene} / {name}")
            print_profile(os.path.join(prof, name), args.top)


def blender_main(argv):
    ap = argparse.ArgumentParser(description="time the add-on on scale scenes in real Blender (bpy)")
    ap.add_argument("--quick", action="store_true",
                    help="a small run: 5,000 objects, 1 M vertices, 3,000 objects over 50 frames")
    ap.add_argument("--objects", type=int, help="objects of the shared and unique scenes (default 50,000)")
    ap.add_argument("--vertices", type=int, help="vertices of the grid mesh (default 10 million)")
    ap.add_argument("--analyze-objects", type=int, default=3000)
    ap.add_argument("--frames", type=int, help="frames of the analyze run (default 200)")
    ap.add_argument("--turns", type=int, default=7, help="passes after each camera turn (to and fro)")
    ap.add_argument("--turn-rad", type=lambda s: [float(x) for x in s.split(",")], default=[0.01, 0.1],
                    help="camera turns, comma-separated radians (default 0.01,0.1: the larger one brings "
                         "columns of objects into the view and takes others out)")
    ap.add_argument("--hide-in", default="AUTO", choices=("AUTO", "VIEW", "EVERYWHERE"),
                    help="the add-on's Hide In setting (AUTO in background mode: everywhere, hide_viewport; "
                         "VIEW: the window's 3D view's local-view bits)")
    ap.add_argument("--only", default="shared,unique,grid,analyze", help="scenes to run, comma-separated")
    ap.add_argument("--profile", help="a folder for cProfile output of each phase")
    ap.add_argument("--top", type=int, default=0, help="print the top N profile entries of each phase")
    ap.add_argument("--steps", action="store_true",
                    help="also time the first cull's steps (extraction, chunking, hierarchy, upload, "
                         "pass), each with its peak resident set above the scene's own")
    ap.add_argument("--strategy", help="the add-on's strategy setting (default: the add-on's default)")
    ap.add_argument("--envelope", action="store_true",
                    help="each Cull click hides only what stays hidden for live mode's envelope at rest, as "
                         "a click from a 3D view does (the scene's Live setting on: background mode runs no "
                         "timers, so nothing else of live mode runs)")
    ap.add_argument("--json", help="write every scene's rows here")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--zip", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    args.objects = args.objects or (5000 if args.quick else 50_000)
    args.vertices = args.vertices or (1_000_000 if args.quick else 10_000_000)
    args.frames = args.frames or (50 if args.quick else 200)
    if args.child:
        args.scene = args.child
        return child_main(args)
    work = tempfile.mkdtemp(prefix="occ_scale_")
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    from build_extension import plain_zip
    zip_path = plain_zip(os.path.join(work, "dist"))
    results = []
    for name in args.only.split(","):
        env = {**os.environ, "BLENDER_USER_RESOURCES": os.path.join(work, f"user_{name}")}
        cmd = [sys.executable, os.path.abspath(__file__), *argv, "--child", name, "--zip", zip_path]
        p = subprocess.Popen(cmd, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        for line in p.stdout:                  # each scene in a fresh Blender: its memory is its own
            if line.startswith("SCALE_RESULT "):
                results.append(json.loads(line[len("SCALE_RESULT "):]))
            else:
                print(line, end="", flush=True)
        if p.wait() != 0:
            print(f"scene '{name}' failed (exit {p.returncode})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    bad = [r["scene"] for r in results if r.get("false_negatives")]
    return 1 if bad or len(results) != len(args.only.split(",")) else 0


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["engine"]:
        ap = argparse.ArgumentParser(description="the grid scene in the engine alone")
        ap.add_argument("--vertices", type=int, default=10_000_000)
        ap.add_argument("--chunk-triangles", type=int, default=4096)
        ap.add_argument("--turns", type=int, default=5)
        ap.add_argument("--profile", help="a folder for cProfile output of each phase")
        ap.add_argument("--top", type=int, default=20)
        ap.add_argument("--numpy", action="store_true",
                        help="also trace allocations (tracemalloc: numpy's arrays) per phase, above those "
                             "held before the engine; exact where resident sizes keep freed memory, "
                             "but slower: compare times without it")
        ap.add_argument("--json")
        args = ap.parse_args(argv[1:])
        if args.profile:
            os.makedirs(args.profile, exist_ok=True)
        return engine_main(args)
    return blender_main(argv)


if __name__ == "__main__":
    sys.exit(main())
