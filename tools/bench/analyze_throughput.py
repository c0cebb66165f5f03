"""Throughput of scripted camera-path analysis on city-xl (28,845 objects), headless and
in Blender (bpy), in one process and in two: a timing script, not a test.

    .venv/bin/python tools/bench/analyze_throughput.py [--frames 300] [--work DIR] [--jobs2-frames N]
                                                [--only headless,bpy] [--json OUT]

1. A camera path of ``--frames`` frames over city-xl, interpolated from the sample's own
   path (eye and target linearly, the same lens), written as camera JSON to ``--work``
   (default: a new temporary folder; nothing here is committed).
2. Headless: ``python -m core analyze city-xl --camera PATH.json --out DIR --jobs 1`` and
   ``--jobs 2`` as subprocesses, and the farm recipe by hand (two ``analyze --frames``
   chunks at once, then ``merge``), which, unlike ``--jobs 2``, prints each chunk's
   progress.
3. bpy: the add-on's zip (``tools/build_extension.py --no-wheels``) installed into an
   isolated ``BLENDER_USER_RESOURCES`` as the Blender tests do; city-xl built once
   (``tools/blender_scene.build_scene``) with a scene camera keyed on every frame of the
   same path (lens, aspect, clipping of the JSON; render size 640x360, the headless query
   resolution) and saved as a .blend; then ``occ.analyze`` over the whole range in one
   bpy process, and over two halves in two bpy processes at once followed by
   ``python -m core merge``.
4. A table: wall clock and frames/s of each run, the set-up before the first frame's pass
   (start, imports, scene load and engine build) and the milliseconds per frame of the
   passes alone, per process.  The per-frame time comes from the progress lines each run
   prints (about every tenth of its frames), stamped as they arrive: the time between the
   first and the last line over the frames between them, so the first frame's build is
   not in it.
5. The per-frame visible sets of the bpy reports against the headless report's (bpy
   frame ``f`` is path index ``f - 1``), and the bpy camera (the add-on's
   ``scene_camera``) against the JSON camera, matrix by matrix.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXT_ID = "occlusion_culled_viewport"
MODULE = f"bl_ext.user_default.{EXT_ID}"
SCENE = "city-xl"
RENDER = (640, 360)          # the headless default query resolution; 16:9 as the path's aspect
HEADLESS_LINE = re.compile(r"^\s*\[(\d+)/(\d+)\] frame")
BPY_LINE = re.compile(r"^occlusion analyze: (\d+)/(\d+) frames \(([\d.]+) s\)")


# --- the camera path ----------------------------------------------------------------------
def make_path(n):
    """``n`` cameras from the sample's own path: eye and target interpolated linearly
    between its frames, every other value (lens, aspect, clipping, up) its own."""
    sys.path.insert(0, ROOT)
    import sample_scenes  # the path core.lab.jobs.resolve_cameras gives `analyze city-xl`
    src = sample_scenes.default_camera_path(SCENE)["frames"]
    eyes = np.array([c["eye"] for c in src], dtype=np.float64)
    targets = np.array([c["target"] for c in src], dtype=np.float64)
    s = np.linspace(0.0, len(src) - 1, n)
    frames = []
    for x in s:
        i = min(int(np.floor(x)), len(src) - 2)
        t = x - i
        cam = dict(src[i])
        cam["eye"] = [float(v) for v in (1 - t) * eyes[i] + t * eyes[i + 1]]
        cam["target"] = [float(v) for v in (1 - t) * targets[i] + t * targets[i + 1]]
        frames.append(cam)
    return {"frames": frames}


# --- running and stamping processes ---------------------------------------------------------
class Proc:
    """A subprocess whose output lines are stamped (seconds since ``t0``) as they arrive."""

    def __init__(self, name, cmd, t0, env=None, cwd=ROOT):
        self.name, self.cmd, self.t0 = name, cmd, t0
        self.start = time.perf_counter() - t0
        self.p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True, bufsize=1)
        self.lines = []
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self):
        for line in self.p.stdout:
            self.lines.append((time.perf_counter() - self.t0, line.rstrip("\n")))

    def wait(self):
        rc = self.p.wait()
        self.thread.join()
        self.end = time.perf_counter() - self.t0
        if rc != 0:
            tail = "\n".join(text for _, text in self.lines[-40:])
            raise SystemExit(f"{self.name} failed (exit {rc}): {' '.join(self.cmd)}\n{tail}")
        return self

    def child_result(self):
        """The JSON of a bpy child's ``THROUGHPUT_CHILD`` line."""
        for _, text in self.lines:
            if text.startswith("THROUGHPUT_CHILD "):
                return json.loads(text[len("THROUGHPUT_CHILD "):])
        raise SystemExit(f"{self.name} printed no result:\n" + "\n".join(t for _, t in self.lines[-40:]))


def run_together(specs, env=None):
    """Start every ``(name, cmd)`` at once; -> (wall seconds, the finished Procs)."""
    t0 = time.perf_counter()
    procs = [Proc(name, cmd, t0, env) for name, cmd in specs]
    for p in procs:
        p.wait()
    return time.perf_counter() - t0, procs


def per_frame(proc, pattern):
    """From a process's stamped progress lines: (seconds per frame of the passes between
    its first and last line, seconds from its start to the first frame's pass done
    less those frames, i.e. its set-up), or (None, None) without two lines."""
    marks = [(t, int(m.group(1))) for t, text in proc.lines if (m := pattern.match(text))]
    if len(marks) < 2 or marks[-1][1] == marks[0][1]:
        return None, None
    (t1, k1), (t2, k2) = marks[0], marks[-1]
    spf = (t2 - t1) / (k2 - k1)
    return spf, t1 - proc.start - k1 * spf


# --- headless --------------------------------------------------------------------------------
def headless_rows(work, camera, n):
    py = sys.executable
    rows, reports = [], {}
    for jobs in (1, 2):
        out = os.path.join(work, f"headless_jobs{jobs}")
        cmd = [py, "-m", "core", "analyze", SCENE, "--camera", camera, "--out", out, "--jobs", str(jobs)]
        print(f"headless --jobs {jobs}: {' '.join(cmd)}", flush=True)
        wall, (p,) = run_together([(f"headless jobs {jobs}", cmd)])
        spf, setup = per_frame(p, HEADLESS_LINE) if jobs == 1 else (None, None)
        rows.append(row("headless", f"analyze --jobs {jobs}", n, jobs, wall, [spf] if spf else [],
                        [setup] if setup is not None else []))
        reports[f"headless_jobs{jobs}"] = os.path.join(out, "report.json")
        print_row(rows[-1])
    # the farm recipe by hand: two chunks at once (each prints its progress), then merge
    half = n // 2
    chunks = [(0, half), (half, n)]
    base = os.path.join(work, "headless_chunks")
    specs = [(f"headless chunk {a}:{b}", [py, "-m", "core", "analyze", SCENE, "--camera", camera,
                                          "--frames", f"{a}:{b}", "--out", os.path.join(base, f"chunk_{a}")])
             for a, b in chunks]
    print("headless chunks: " + " & ".join(" ".join(c) for _, c in specs), flush=True)
    t0 = time.perf_counter()
    _, procs = run_together(specs)
    merged = os.path.join(work, "headless_chunks_merged")
    subprocess.run([py, "-m", "core", "merge", *(os.path.join(base, f"chunk_{a}") for a, _ in chunks),
                    "--out", merged], cwd=ROOT, check=True, capture_output=True, timeout=600)
    wall = time.perf_counter() - t0
    fits = [per_frame(p, HEADLESS_LINE) for p in procs]
    rows.append(row("headless", "2 x analyze --frames, merge", n, 2, wall,
                    [s for s, _ in fits if s], [u for _, u in fits if u is not None]))
    reports["headless_chunks"] = os.path.join(merged, "report.json")
    print_row(rows[-1])
    return rows, reports


# --- bpy ---------------------------------------------------------------------------------------
def build_zip(work):
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    from build_extension import plain_zip
    return plain_zip(os.path.join(work, "dist"))


def bpy_rows(work, camera, n, n2):
    env = {**os.environ, "BLENDER_USER_RESOURCES": os.path.join(work, "user")}
    me = os.path.abspath(__file__)
    py = sys.executable
    blend = os.path.join(work, "city_xl_path.blend")
    t = time.perf_counter()
    zip_path = build_zip(work)
    _, (p,) = run_together([("bpy build", [py, me, "--child", "build", "--zip", zip_path, "--camera", camera,
                                           "--blend", blend])], env)
    built = p.child_result()
    print(f"bpy: city-xl built, camera keyed on {n} frames, saved {blend} in {time.perf_counter() - t:.1f} s "
          f"(scene {built['build_s']:.1f} s); camera vs JSON: view max |diff| {built['view_diff']:.2e}, "
          f"projection max |diff| {built['projection_diff']:.2e}", flush=True)
    rows, reports, children = [], {}, {}

    def analyze(name, a, b, path):
        return (name, [py, me, "--child", "analyze", "--blend", blend, "--start", str(a), "--end", str(b),
                       "--report", path])

    path1 = os.path.join(work, "bpy_jobs1", "report.json")
    spec = analyze("bpy jobs 1", 1, n, path1)
    spec[1].append("--breakdown")
    print(f"bpy, 1 process: {' '.join(spec[1])}", flush=True)
    wall, (p,) = run_together([spec], env)
    spf, setup = per_frame(p, BPY_LINE)
    res = p.child_result()
    children["jobs1"] = [res]
    rows.append(row("bpy", "occ.analyze, 1 process", n, 1, wall, [spf] if spf else [],
                    [setup] if setup is not None else [], open_s=[res["open_s"]], op_s=[res["op_s"]]))
    reports["bpy_jobs1"] = path1
    print_row(rows[-1])
    for k, v in res.get("breakdown_ms", {}).items():
        print(f"    per frame, median: {k}: {v:.0f} ms", flush=True)
    for k, v in res.get("calls", {}).items():
        print(f"    calls over {n} frames: {k}: {v}", flush=True)

    half = n2 // 2
    chunks = [(1, half), (half + 1, n2)]
    folder = os.path.join(work, "bpy_chunks")
    specs = [analyze(f"bpy chunk {a}-{b}", a, b, os.path.join(folder, f"chunk_{a}_{b}.json")) for a, b in chunks]
    print("bpy, 2 processes: " + " & ".join(" ".join(c) for _, c in specs), flush=True)
    t0 = time.perf_counter()
    _, procs = run_together(specs, env)
    merged = os.path.join(work, "bpy_chunks_merged")
    merge = [py, "-m", "core", "merge", folder, "--out", merged]
    print(f"  then: {' '.join(merge)}", flush=True)
    subprocess.run(merge, cwd=ROOT, check=True, capture_output=True, timeout=600)
    wall = time.perf_counter() - t0
    fits = [per_frame(p, BPY_LINE) for p in procs]
    results = [p.child_result() for p in procs]
    children["jobs2"] = results
    rows.append(row("bpy", "2 x occ.analyze chunks, merge", n2, 2, wall, [s for s, _ in fits if s],
                    [u for _, u in fits if u is not None], open_s=[r["open_s"] for r in results],
                    op_s=[r["op_s"] for r in results]))
    reports["bpy_chunks"] = os.path.join(merged, "report.json")
    print_row(rows[-1])
    return rows, reports, {"build": built, "analyze": children}


def child_build(args):
    """In bpy: install the add-on (isolated user folder), build city-xl, key the camera
    on every frame of the path, check it against the JSON cameras, save the .blend."""
    import bpy
    import mathutils
    sys.path.insert(0, ROOT)
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    from blender_scene import build_scene

    import sample_scenes
    from core import load_cameras, load_scene

    bpy.ops.extensions.package_install_files(filepath=args.zip, repo="user_default", enable_on_install=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    t = time.perf_counter()
    build_scene(load_scene(sample_scenes.scene_path(SCENE)))
    build_s = time.perf_counter() - t
    with open(args.camera) as f:
        path = json.load(f)["frames"]
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = RENDER
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    if abs(RENDER[0] / RENDER[1] - path[0]["aspect"]) > 1e-9:
        raise SystemExit(f"the render size {RENDER} does not have the path's aspect {path[0]['aspect']}")
    scene.frame_start, scene.frame_end = 1, len(path)
    data = bpy.data.cameras.new("throughput_camera")
    data.type = "PERSP"
    data.sensor_fit = "VERTICAL"               # the JSON's fov is vertical
    data.angle_y = np.radians(path[0]["fov_y_deg"])
    data.clip_start, data.clip_end = path[0]["near"], path[0]["far"]
    data.shift_x = data.shift_y = 0.0
    cam = bpy.data.objects.new("throughput_camera", data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.rotation_mode = "XYZ"
    euler = None
    for f, c in enumerate(path, start=1):
        for key in ("fov_y_deg", "near", "far", "aspect"):
            if c[key] != path[0][key]:
                raise SystemExit(f"frame {f}: {key} changes along the path; the camera keeps the first frame's")
        eye, target = np.array(c["eye"]), np.array(c["target"])
        up = np.array(c.get("up") or (0.0, 0.0, 1.0))
        fwd = (target - eye) / np.linalg.norm(target - eye)
        right = np.cross(fwd, up)
        right /= np.linalg.norm(right)
        true_up = np.cross(right, fwd)
        m = mathutils.Matrix(np.column_stack([right, true_up, -fwd]).tolist())   # camera: -Z ahead, +Y up
        euler = m.to_euler("XYZ", euler) if euler is not None else m.to_euler("XYZ")
        cam.location = [float(v) for v in eye]
        cam.rotation_euler = euler
        cam.keyframe_insert("location", frame=f)
        cam.keyframe_insert("rotation_euler", frame=f)
    # the add-on's camera of every frame against the engine's camera of the JSON
    cameras = sys.modules[f"{MODULE}.occ_addon.cameras"]
    want = load_cameras(args.camera)
    dv = dp = 0.0
    seen_by = np.zeros((len(path), 2, 4, 4))          # each frame's (view, projection) as the add-on reads it
    for f in range(1, len(path) + 1):
        scene.frame_set(f)
        got, size = cameras.scene_camera(bpy.context)
        seen_by[f - 1] = got.view, got.projection
        dv = max(dv, float(np.abs(got.view - want[f - 1].view).max()))
        dp = max(dp, float(np.abs(got.projection - want[f - 1].projection).max()))
    scene.frame_set(1)
    # the engine's objects as the add-on reads them: view-layer order, matrix_world (float32)
    layer = [o for o in bpy.context.view_layer.objects if o.type == "MESH"]
    mats = np.zeros(len(layer) * 16, dtype=np.float32)
    for k, o in enumerate(layer):
        mats[16 * k:16 * k + 16] = np.array(o.matrix_world, dtype=np.float32).ravel()
    np.savez(os.path.join(os.path.dirname(args.blend), "blender_objects.npz"),
             names=np.array([o.name for o in layer]), matrices=mats.reshape(-1, 4, 4), cameras=seen_by)
    bpy.ops.wm.save_as_mainfile(filepath=args.blend)
    print("THROUGHPUT_CHILD " + json.dumps({"build_s": build_s, "objects": len(bpy.data.objects),
                                            "view_diff": dv, "projection_diff": dp, "size": list(size)}),
          flush=True)
    bpy.ops.preferences.addon_disable(module=MODULE)


def watch_addon():
    """Time, call by call, what ``occ.analyze`` does per frame besides ``frame_set``: the
    candidates (every object of the view layer read again, where the frames are evaluated
    one by one; read once where the camera comes from its keys), the engine's pass (on the
    add-on's engine thread) and the objects drawn beside the engine's (read once with the
    keys).  -> {step: [seconds per call]}, filled as the analysis runs."""
    calls = {"add-on candidates (Session.candidates)": [], "engine pass (Culler.cull)": [],
             "objects beside the engine's (drawn.bystanders)": []}

    def timed(fn, key):
        def call(*a, **k):
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                calls[key].append(time.perf_counter() - t)
        return call
    try:
        session = sys.modules[f"{MODULE}.occ_addon.session"].SESSION
        engine = sys.modules[f"{MODULE}.core.engine"]
        policy = sys.modules[f"{MODULE}.occ_addon.policy"]
        keys = list(calls)
        session.candidates = timed(session.candidates, keys[0])
        engine.Culler.cull = timed(engine.Culler.cull, keys[1])
        policy.bystanders = timed(policy.bystanders, keys[2])
    except (KeyError, AttributeError) as e:   # the add-on's internals changed: time without
        print(f"breakdown unavailable: {type(e).__name__}: {e}", flush=True)
        return {}
    return calls


def child_analyze(args):
    """In bpy: enable the add-on, open the .blend, ``occ.analyze`` frames start..end."""
    import bpy  # noqa: I001 -- first: Blender's own modules (addon_utils) come with it
    import addon_utils
    t = time.perf_counter()
    if addon_utils.enable(MODULE, default_set=True, persistent=True) is None:
        raise SystemExit(f"cannot enable {MODULE}")
    enable_s = time.perf_counter() - t
    t = time.perf_counter()
    bpy.ops.wm.open_mainfile(filepath=args.blend)
    open_s = time.perf_counter() - t
    calls = watch_addon() if args.breakdown else {}
    t = time.perf_counter()
    r = bpy.ops.occ.analyze(frame_start=args.start, frame_end=args.end, frame_step=1, rule="SEEN",
                            filepath=args.report)
    op_s = time.perf_counter() - t
    if r != {"FINISHED"}:
        raise SystemExit(f"occ.analyze returned {r}")
    out = {"enable_s": enable_s, "open_s": open_s, "op_s": op_s}
    if calls:
        # steady state: every call after the first frame's (which reads geometry and builds)
        out["breakdown_ms"] = {k: 1e3 * float(np.median(v[1:])) for k, v in calls.items() if len(v) > 1}
        out["calls"] = {k: len(v) for k, v in calls.items()}
        scene, times = bpy.context.scene, []
        for f in range(args.start, min(args.end, args.start + 10) + 1):
            t = time.perf_counter()
            scene.frame_set(f)
            times.append(time.perf_counter() - t)
        out["breakdown_ms"]["scene.frame_set (apart, after the run)"] = 1e3 * float(np.median(times))
    print("THROUGHPUT_CHILD " + json.dumps(out), flush=True)
    # disabled while its engine thread lives (at exit, bpy 5.0.1's unregister finds the pool gone)
    bpy.ops.preferences.addon_disable(module=MODULE)


# --- the table and the comparison ----------------------------------------------------------
def row(runner, how, frames, processes, wall, spf, setup, **extra):
    return {"runner": runner, "how": how, "frames": frames, "processes": processes, "wall_s": wall,
            "frames_per_s": frames / wall, "ms_per_frame": [1e3 * s for s in spf], "setup_s": setup, **extra}


def _mean(xs):
    return sum(xs) / len(xs) if xs else None


def _fmt(x, spec):
    return format(x, spec) if x is not None else "-"


def print_row(r):
    ms = " / ".join(f"{x:.0f}" for x in r["ms_per_frame"]) or "-"
    setup = " / ".join(f"{x:.1f}" for x in r["setup_s"]) or "-"
    print(f"  {r['runner']:<9}{r['how']:<31}{r['frames']:>7}{r['processes']:>6}{r['wall_s']:>9.1f}"
          f"{r['frames_per_s']:>9.2f}{setup:>14}{ms:>14}", flush=True)


def print_table(rows, ratios):
    print(f"\n  {'runner':<9}{'how':<31}{'frames':>7}{'procs':>6}{'wall s':>9}{'frames/s':>9}"
          f"{'set-up s':>14}{'ms/frame':>14}")
    for r in rows:
        print_row(r)
    print("  (set-up: start to the first frame's pass done, less the passes; ms/frame: the passes alone,")
    print("   per process; two values: each process's)")
    for label, v in ratios.items():
        print(f"  bpy / headless per frame, {label}: {_fmt(v, '.2f')}")


def compare(bpy_path, headless_path):
    """Per-frame visible sets of a bpy report (frames 1..) against a headless one (0..)."""
    with open(bpy_path) as f:
        b = json.load(f)
    with open(headless_path) as f:
        h = json.load(f)
    hv = {fr["frame"]: set(fr["visible"]) for fr in h["frames"]}
    out = {"frames": 0, "equal": 0, "differ": [], "only_bpy": {}, "only_headless": {}}
    for fr in b["frames"]:
        k = fr["frame"] - 1
        if k not in hv:
            continue
        out["frames"] += 1
        got, want = set(fr["visible"]), hv[k]
        if got == want:
            out["equal"] += 1
            continue
        out["differ"].append({"frame": fr["frame"], "index": k, "only_bpy": sorted(got - want),
                              "only_headless": sorted(want - got), "bpy": len(got), "headless": len(want)})
        for n in got - want:
            out["only_bpy"][n] = out["only_bpy"].get(n, 0) + 1
        for n in want - got:
            out["only_headless"][n] = out["only_headless"].get(n, 0) + 1
    out["names_bpy_only"] = sorted(set(b["objects"]) - set(h["objects"]))
    out["names_headless_only"] = sorted(set(h["objects"]) - set(b["objects"]))
    return out


def replay(work, camera, bpy_report):
    """The headless engine on the objects as the add-on reads them from Blender (view-layer
    order, float32 world matrices; the build saved both), every frame of ``bpy_report`` a
    new engine's first pass, once with the JSON cameras and once with the cameras the
    add-on read from Blender: -> (frames, equal to the report's with the JSON cameras,
    equal with Blender's)."""
    import sample_scenes
    from core import DEFAULT_STRATEGY, Camera, Culler, Scene, Visibility, load_cameras, load_scene
    src = load_scene(sample_scenes.scene_path(SCENE))
    saved = np.load(os.path.join(work, "blender_objects.npz"))
    names = [str(x) for x in saved["names"]]
    where = {n: i for i, n in enumerate(src.names)}
    order = [where[n] for n in names]
    scene = Scene.from_arrays(names, list(src.meshes), [int(src.mesh_of[i]) for i in order],
                              [m.astype(np.float64) for m in saved["matrices"]])
    cams = load_cameras(camera)
    with open(bpy_report) as f:
        frames = json.load(f)["frames"]
    blender = [Camera.from_matrices(v, p) for v, p in saved["cameras"]]
    equal = [0, 0]
    # chunk_triangles: the add-on's (occ_addon.session.CHUNK_TRIANGLES)
    with Culler(scene, RENDER, strategy=DEFAULT_STRATEGY, chunk_triangles=4096) as culler:
        for fr in frames:
            for k, path in enumerate((cams, blender)):
                state = culler.cull(path[fr["frame"] - 1], fresh=True).state
                equal[k] += {names[i] for i in np.flatnonzero(state == Visibility.VISIBLE)} == set(fr["visible"])
    return len(frames), *equal


def print_compare(label, c):
    print(f"  {label}: {c['equal']} of {c['frames']} frames have the same visible set", flush=True)
    if c["names_bpy_only"] or c["names_headless_only"]:
        print(f"    objects only bpy knows: {c['names_bpy_only'][:5]} ({len(c['names_bpy_only'])}); "
              f"only headless: {c['names_headless_only'][:5]} ({len(c['names_headless_only'])})")
    if c["differ"]:
        d = c["differ"]
        print(f"    over the {len(d)} frames that differ: {sum(x['bpy'] for x in d) / len(d):.0f} objects visible in "
              f"bpy, {sum(x['headless'] for x in d) / len(d):.0f} headless on average; "
              f"{sum(len(x['only_bpy']) for x in d)} object-frames only in bpy, "
              f"{sum(len(x['only_headless']) for x in d)} only headless")
    for d in c["differ"][:3]:
        print(f"    frame {d['frame']} (path index {d['index']}): bpy {d['bpy']}, headless {d['headless']}; "
              f"only bpy {d['only_bpy'][:2]}{'...' if len(d['only_bpy']) > 2 else ''}, "
              f"only headless {d['only_headless'][:2]}{'...' if len(d['only_headless']) > 2 else ''}")


def main(argv=None):
    ap = argparse.ArgumentParser(description="frames per second of analyze on city-xl, headless and in bpy")
    ap.add_argument("--frames", type=int, default=300, help="frames of the camera path (default 300)")
    ap.add_argument("--jobs2-frames", type=int, help="frames of the two-process bpy run (default --frames)")
    ap.add_argument("--work", help="a folder for the path, the .blend and the reports (default: a new temp folder)")
    ap.add_argument("--only", default="headless,bpy", help="headless, bpy or both (comma-separated)")
    ap.add_argument("--json", help="write the rows, ratios and comparisons here")
    ap.add_argument("--child", choices=["build", "analyze"], help=argparse.SUPPRESS)
    ap.add_argument("--zip", help=argparse.SUPPRESS)
    ap.add_argument("--camera", help=argparse.SUPPRESS)
    ap.add_argument("--blend", help=argparse.SUPPRESS)
    ap.add_argument("--start", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--end", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--report", help=argparse.SUPPRESS)
    ap.add_argument("--breakdown", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child == "build":
        return child_build(args)
    if args.child == "analyze":
        return child_analyze(args)

    n = args.frames
    n2 = args.jobs2_frames or n
    if n < 20 or n2 < 20:
        raise SystemExit("--frames and --jobs2-frames must be at least 20 (progress lines every tenth)")
    if n2 > n:
        raise SystemExit("--jobs2-frames cannot exceed --frames (its frames are the path's first)")
    only = set(args.only.split(","))
    work = os.path.abspath(args.work or tempfile.mkdtemp(prefix="occ_throughput_"))
    os.makedirs(work, exist_ok=True)
    sys.path.insert(0, ROOT)
    import sample_scenes
    sample_scenes.scene_path(SCENE)                     # generated (and cached) before any timing
    camera = os.path.join(work, f"{SCENE}_{n}.json")
    with open(camera, "w") as f:
        json.dump(make_path(n), f)
    print(f"{SCENE}: camera path of {n} frames in {camera}; work folder {work}", flush=True)

    rows, reports, extra = [], {}, {}
    if "headless" in only:
        r, rep = headless_rows(work, camera, n)
        rows += r
        reports.update(rep)
    if "bpy" in only:
        r, rep, extra = bpy_rows(work, camera, n, n2)
        rows += r
        reports.update(rep)

    ratios = {}
    by = {r["how"]: r for r in rows}
    h1, b1 = by.get("analyze --jobs 1"), by.get("occ.analyze, 1 process")
    h2, b2 = by.get("2 x analyze --frames, merge"), by.get("2 x occ.analyze chunks, merge")
    if h1 and b1 and h1["ms_per_frame"] and b1["ms_per_frame"]:
        ratios["1 process"] = _mean(b1["ms_per_frame"]) / _mean(h1["ms_per_frame"])
    if h2 and b2 and h2["ms_per_frame"] and b2["ms_per_frame"]:
        ratios["2 processes"] = _mean(b2["ms_per_frame"]) / _mean(h2["ms_per_frame"])
    print_table(rows, ratios)

    comparisons = {}
    if "headless_jobs1" in reports:
        if "bpy_jobs1" in reports:
            comparisons["bpy_jobs1 vs headless_jobs1"] = compare(reports["bpy_jobs1"], reports["headless_jobs1"])
        for key in ("headless_jobs2", "headless_chunks"):
            with open(reports[key]) as f, open(reports["headless_jobs1"]) as g:
                same = json.load(f)["frames"] == json.load(g)["frames"]
            print(f"  {key}: per-frame visible sets {'equal to' if same else 'DIFFER from'} --jobs 1's")
    if "bpy_jobs1" in reports and "bpy_chunks" in reports:
        with open(reports["bpy_chunks"]) as f, open(reports["bpy_jobs1"]) as g:
            one = {fr["frame"]: fr["visible"] for fr in json.load(g)["frames"]}
            same = all(one.get(fr["frame"]) == fr["visible"] for fr in json.load(f)["frames"])
        print(f"  bpy_chunks (merged): per-frame visible sets {'equal to' if same else 'DIFFER from'} one process's")
    print("\nvisible sets, bpy against headless (bpy frame f = path index f - 1):")
    for label, c in comparisons.items():
        print_compare(label, c)
    if "bpy_jobs1" in reports:
        n_frames, equal, equal_blender = replay(work, camera, reports["bpy_jobs1"])
        comparisons["replay"] = {"frames": n_frames, "equal_json_cameras": equal,
                                 "equal_blender_cameras": equal_blender}
        print(f"  the headless engine on Blender's objects (view-layer order, float32 matrices): "
              f"{equal} of {n_frames} frames have bpy's visible set with the JSON cameras, "
              f"{equal_blender} with the cameras the add-on read from Blender")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"frames": n, "jobs2_frames": n2, "camera": camera, "rows": rows, "ratios": ratios,
                       "comparisons": comparisons, "bpy": extra, "reports": reports}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
