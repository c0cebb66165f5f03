"""A long session of the add-on in real Blender (bpy from PyPI, headless), issue 30:

    .venv/bin/python tools/checks/soak.py [--scene city] [--scale 1.0] [--only live,cull,...]
                                   [--json OUT] [--work DIR] [--keep]

Installs the extension as a user does (``tools/build_extension.py --no-wheels``, then
``extensions.package_install_files`` into an isolated ``BLENDER_USER_RESOURCES``),
builds SCENE (default ``city``, 3,205 objects) as Blender objects, puts the scene
camera on the scene's camera path and runs, at ``--scale`` 1 (the issue's sizes):

- ``live``: 5,000 live passes (``live._tick`` driven by hand: headless Blender runs no
  timers), the scene camera moved along the path before each;
- ``cull``: 500 Cull/Restore cycles (``occ.cull``, ``occ.restore``) from changing views;
- ``undo_control``: 200 undo/redo pairs without the add-on's operations (an edit,
  ``ed.undo``, ``ed.redo``): Blender's own undo memory, reported and not a target (with
  no engine job, nothing calls ``malloc_trim``, and glibc keeps what Blender freed);
- ``undo``: 200 undo/redo pairs (an edit and a Cull, ``ed.undo``, a Cull, ``ed.redo``,
  a Cull, Restore); its trend target counts only the rise beyond ``undo_control``'s;
- ``toggle``: 50 disable/enable cycles of the extension (live on and a live pass before
  each disable, a Cull and Restore after each enable);
- ``control``: the same number of disable/enable cycles of a trivial extension (no
  GL, no thread): Blender's own cost of toggling an extension;
- ``save``: 20 save/reload cycles (a Cull, ``wm.save_as_mainfile``, ``wm.open_mainfile``,
  a Cull, Restore).

Watched over time (a sample every few cycles): resident memory (``VmRSS``); the GL
objects alive (moderngl's wrappers found by ``gc``, not released, of a context not
released: buffers, textures, framebuffers, renderbuffers, programs, vertex arrays,
queries, contexts) and released contexts still referenced; the length of every
``bpy.app.handlers`` list and how many of the add-on's functions they hold; the
add-on's timers (``bpy.app.timers.is_registered``) and draw handlers; the engine
thread (alive, queued jobs, ``occ-engine`` threads); the process's threads and file
descriptors.  After every cycle the registrations and the engine thread must be as
before the phase (after its first cycle), and at every sample the GL objects too;
after every Restore, disable and reload nothing is hidden and no record is left;
a disabled add-on leaves no handler, timer, draw handler, thread, class, property or
live GL object; no cycle raises and nothing prints a traceback.  Memory: within each
phase, after warm-up, the resident set grows at most 50 MB, and a line fitted to its
samples rises at most 10 MB (no upward trend).  Warm-up is the phase's first tenth, or,
in a phase that moves the view, the cycles that take it along the whole camera path and
back (at most half the phase): what a pass holds (the candidates, the geometry read,
the GL uploads) follows the view, so the resident set is only all there once every
view was seen (the live phase's 5,000 passes go along the city's path 3.5 times).

Prints a table per phase and a timeline; ``--json`` writes the whole record.  Exits 1
when a target fails.  ``--scale 0.1`` runs a tenth of every count (at least 3 each),
``--count live=200`` sets one; ``--without-thread-release`` runs the engine thread as it
was before issue 30's fix (it ended with its EGL context current: about 20 MB kept per
disable/enable on the city), to show what the toggle phase catches.  ``--trace-malloc``
traces Python's allocations (numpy's arrays too, not the GL driver's) and prints, per
phase, the sites that grew after warm-up.
"""

import argparse
import gc
import json
import math
import os
import sys
import tempfile
import threading
import time
import traceback
import tracemalloc
import zipfile

WORK = None
if __name__ == "__main__":      # the user folder must be set before bpy starts
    ap0 = argparse.ArgumentParser(add_help=False)
    ap0.add_argument("--work")
    WORK = ap0.parse_known_args()[0].work or tempfile.mkdtemp(prefix="occ_soak_")
    os.makedirs(WORK, exist_ok=True)
    os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(WORK, "user"))

import bpy  # noqa: E402
import mathutils  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tools"))
from blender_scene import build_scene  # noqa: E402
from build_extension import plain_zip  # noqa: E402

EXT_ID = "occlusion_culled_viewport"
MOD = f"bl_ext.user_default.{EXT_ID}"
TRIVIAL_ID = "occ_soak_trivial"
TRIVIAL = f"bl_ext.user_default.{TRIVIAL_ID}"
SIZES = {"live": 5000, "cull": 500, "undo_control": 200, "undo": 200, "toggle": 50, "control": 50, "save": 20}
GROWTH_MB = 50.0        # the budget after warm-up
TRACE = False           # --trace-malloc
TREND_MB = 10.0         # what a line fitted to a phase's samples may rise
CAMERA = "soak_camera"
RENDER = (1280, 720)
GL_TYPES = ("Buffer", "Texture", "Texture3D", "TextureArray", "TextureCube", "Framebuffer", "Renderbuffer",
            "Program", "ComputeShader", "VertexArray", "Query", "Sampler", "Scope", "Context")


# --- what is watched -------------------------------------------------------------
def rss_mb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024
    return float("nan")


def addon(module):
    return sys.modules.get(f"{MOD}.occ_addon.{module}")


def gl_census():
    """``(alive by type, released contexts still referenced)``: moderngl's wrappers that
    ``gc`` sees, alive when neither they nor their context were released."""
    import moderngl
    invalid = moderngl.InvalidObject
    types = tuple(getattr(moderngl, n) for n in GL_TYPES if hasattr(moderngl, n))
    gc.collect()
    alive, stale = {}, 0
    for o in gc.get_objects():
        if not isinstance(o, types):
            continue
        name = type(o).__name__
        dead = isinstance(getattr(o, "mglo", invalid), invalid)
        if name == "Context":
            stale += dead
        else:
            ctx = getattr(o, "ctx", None)
            dead = dead or ctx is None or isinstance(getattr(ctx, "mglo", invalid), invalid)
        if not dead:
            alive[name] = alive.get(name, 0) + 1
    return alive, stale


def _ours(f):
    return (getattr(f, "__module__", "") or "").startswith(MOD)


def registrations():
    """What the add-on has registered with Blender and the engine thread's state: every
    value must be the same after every cycle of a phase."""
    h = bpy.app.handlers
    lists = {n: getattr(h, n) for n in dir(h) if not n.startswith("_") and isinstance(getattr(h, n), list)}
    live, overlay, session, bus = addon("live"), addon("overlay"), addon("session"), addon("bus")
    worker = session.SESSION.worker if session is not None else None
    jobs = getattr(worker, "_jobs", None)
    return {
        "handlers": {n: len(v) for n, v in lists.items() if v},
        "addon_handlers": sum(_ours(f) for v in lists.values() for f in v),
        "timers": {name: bool(live is not None and bpy.app.timers.is_registered(getattr(live, name)))
                   for name in ("_tick", "_leave_timer")},
        "draw_handlers": (len(overlay._handles) if overlay is not None else 0)
                         + (len(live._guard_handle) if live is not None else 0),
        "bus_listeners": sum(len(v) for v in bus._listeners.values()) if bus is not None else 0,
        "engine_alive": bool(worker is not None and worker.alive()),
        "engine_queue": jobs.qsize() if jobs is not None else 0,
        "engine_threads": sum(t.name == "occ-engine" and t.is_alive() for t in threading.enumerate()),
        "classes": sum(hasattr(bpy.types, c) for c in ("OCC_OT_cull", "OCC_OT_restore", "OCC_OT_live",
                                                        "OCC_OT_analyze", "OCC_OT_local_view", "OCC_PT_panel")),
        "scene_props": hasattr(bpy.types.Scene, "occ"),
    }


def process():
    return {"threads": len(os.listdir("/proc/self/task")), "fds": len(os.listdir("/proc/self/fd"))}


def nothing():
    """A step that does nothing (the control phases' stand-in for the add-on's)."""


def hidden():
    """``(objects hidden, add-on records left)``; the records read as ID properties where
    the add-on (and its properties) is not registered."""
    objs = bpy.data.objects
    flags = np.zeros(len(objs), dtype=bool)
    objs.foreach_get("hide_viewport", flags)
    if hasattr(bpy.types.Object, "occ_culled"):
        rec = np.zeros(len(objs), dtype=bool)
        objs.foreach_get("occ_culled", rec)
        view = np.zeros(len(objs), dtype=bool)
        objs.foreach_get("occ_view_culled", view)
        records = int((rec | view).sum())
    else:
        records = sum(bool(o.get("occ_culled")) or bool(o.get("occ_view_culled")) for o in objs)
    return int(flags.sum()), records


class Tee:
    """stderr as it was, with every traceback and error line counted (Blender prints a
    handler's or timer's exception there instead of raising it)."""

    def __init__(self, stream):
        self.stream, self.lines = stream, []

    def write(self, s):
        for line in s.splitlines():
            if "Traceback (most recent call last)" in line or line.startswith(("Error", "Exception")):
                self.lines.append(line[:300])
        return self.stream.write(s)

    def flush(self):
        self.stream.flush()

    def __getattr__(self, name):
        return getattr(self.stream, name)


# --- the scene ---------------------------------------------------------------------
def look_matrix(eye, target, up):
    """A camera's world matrix looking from ``eye`` at ``target`` (Blender cameras look down -Z)."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    z = eye - target
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, eye
    return mathutils.Matrix(m.tolist())


class Path:
    """Views along the scene's camera path, ``sub`` steps between its frames, to and fro."""

    def __init__(self, frames, sub=8):
        self.frames, self.sub = frames, sub
        self.n = (len(frames) - 1) * sub

    def cycles(self, step):
        """The cycles that take ``step`` views each along the whole path and back (0: none)."""
        return -(-2 * self.n // step) if step else 0

    def matrix(self, k):
        k = k % (2 * self.n)
        k = k if k <= self.n else 2 * self.n - k
        i, f = divmod(k, self.sub)
        a, b = self.frames[i], self.frames[min(i + 1, len(self.frames) - 1)]
        t = f / self.sub
        lerp = [[(1 - t) * p + t * q for p, q in zip(a[key], b[key], strict=True)] for key in ("eye", "target")]
        return look_matrix(lerp[0], lerp[1], a["up"])


def build(scene_name, small):
    import core
    import sample_scenes
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = core.load_scene(str(sample_scenes.scene_path(scene_name, small=small)))
    build_scene(scene)
    path = sample_scenes.default_camera_path(scene_name, small=small)["frames"]
    first = path[0]
    cam = bpy.data.objects.new(CAMERA, bpy.data.cameras.new(CAMERA))
    bpy.context.scene.collection.objects.link(cam)
    cam.data.sensor_fit = "VERTICAL"
    cam.data.angle_y = math.radians(first["fov_y_deg"])
    cam.data.clip_start, cam.data.clip_end = first["near"], first["far"]
    s = bpy.context.scene
    s.camera = cam
    s.render.resolution_x, s.render.resolution_y = RENDER[0], round(RENDER[0] / first["aspect"])
    s.render.resolution_percentage = 100
    s.occ.source = "CAMERA"
    bpy.context.view_layer.update()
    return len(scene.names), int(scene.triangle_counts.sum()), Path(path)


def trivial_zip(folder):
    """A trivial extension (registers one property, nothing else): the control."""
    path = os.path.join(folder, f"{TRIVIAL_ID}.zip")
    manifest = (f'schema_version = "1.0.0"\nid = "{TRIVIAL_ID}"\nversion = "1.0.0"\nname = "Soak control"\n'
                'tagline = "Does nothing"\nmaintainer = "soak"\ntype = "add-on"\n'
                'blender_version_min = "4.2.0"\nlicense = ["SPDX:GPL-3.0-or-later"]\n')
    init = ("import bpy\n\ndef register():\n    bpy.types.Scene.occ_soak_trivial = bpy.props.IntProperty()\n\n"
            "def unregister():\n    del bpy.types.Scene.occ_soak_trivial\n")
    with zipfile.ZipFile(path, "w") as z:
        z.writestr(f"{TRIVIAL_ID}/blender_manifest.toml", manifest)
        z.writestr(f"{TRIVIAL_ID}/__init__.py", init)
    return path


# --- the soak ----------------------------------------------------------------------
class Soak:
    def __init__(self, path, work, tee):
        self.path, self.work, self.tee = path, work, tee
        self.samples, self.phases, self.checks = [], {}, {}
        self.traced = {}                 # phase: grown(...) (--trace-malloc)
        self.view = 0

    # -- records
    def check(self, name, ok, detail=""):
        """A target: failed once, failed (the first failure's detail is kept)."""
        old = self.checks.get(name)
        if old is None or (old[0] and not ok):
            self.checks[name] = [bool(ok), str(detail)[:1500]]

    def sample(self, phase, cycle, gl=True):
        row = {"phase": phase, "cycle": cycle, "t": round(time.perf_counter() - self.t0, 2), "rss_mb": rss_mb()}
        if gl:
            alive, stale = gl_census()
            row.update(gl_alive=sum(alive.values()), gl=alive, contexts=alive.get("Context", 0),
                       stale_contexts=stale)
        row.update(registrations())
        row.update(process())
        row["hidden"], row["records"] = hidden()
        row["tracebacks"] = len(self.tee.lines)
        self.samples.append(row)
        return row

    # -- steps
    def camera(self):
        return bpy.data.objects[CAMERA]

    def move(self, step=1):
        self.view += step
        self.camera().matrix_world = self.path.matrix(self.view)
        bpy.context.view_layer.update()

    def op(self, name, **kw):
        ns, fn = name.split(".")
        r = getattr(getattr(bpy.ops, ns), fn)(**kw)
        if "FINISHED" not in r:
            raise RuntimeError(f"bpy.ops.{name} returned {r}")
        return r

    def nothing_hidden(self, name, when):
        h, rec = hidden()
        self.check(name, h == 0 and rec == 0, f"{when}: {h} hidden, {rec} records")

    def live_pass(self):
        """One live pass: ticks until the session applied a pass (the first tick sees the
        view changed, the next one, the view at rest, passes)."""
        live, session = addon("live"), addon("session").SESSION
        before = session.version
        for _ in range(4):
            live._tick()
            live.settle()
            if session.version != before:
                return True
        return False

    # -- phases
    def run(self, name, cycles, body, step=0, control=None, judged=True):
        """Run ``body(k)`` ``cycles`` times; registrations compared after every cycle, GL
        objects and memory at the samples, with the state after the first cycle as
        the phase's own "before".  ``step``: the path views a cycle moves (warm-up takes
        the whole path, see the module's doc); ``control``: the phase that ran the same
        cycles without the add-on's operations, whose fitted rise is Blender's own;
        ``judged``: False for such a control, whose memory is reported, not a target."""
        print(f"--- {name}: {cycles} cycles", flush=True)
        every = max(1, cycles // 25)
        warm = max(1, cycles // 10, min(self.path.cycles(step), cycles // 2))
        t = time.perf_counter()
        start = self.sample(name, 0)
        ref, ref_gl, errors = None, None, 0
        traced = None
        for k in range(1, cycles + 1):
            if TRACE and k == warm + 1:
                traced = tracemalloc.take_snapshot()
            try:
                body(k)
            except Exception:  # every failure is recorded, the soak goes on
                errors += 1
                self.check(f"{name}_no_exception", False, traceback.format_exc())
                if errors >= 5:
                    print(f"{name}: 5 failures, phase stopped", flush=True)
                    break
            reg = registrations()
            if ref is None:
                ref = reg
            else:
                self.check(f"{name}_registrations_constant", reg == ref, {"cycle": k, "now": reg, "before": ref})
            if k == 1 or k % every == 0 or k == cycles:
                row = self.sample(name, k)
                if ref_gl is None:
                    ref_gl = row["gl"]
                self.check(f"{name}_gl_objects_constant", row["gl"] == ref_gl,
                           {"cycle": k, "now": row["gl"], "before": ref_gl})
                print(f"{name} {k}/{cycles}: {row['rss_mb']:.0f} MB, {row['gl_alive']} GL objects, "
                      f"{row['stale_contexts']} released contexts kept, {time.perf_counter() - t:.0f} s", flush=True)
        self.check(f"{name}_no_exception", errors == 0, "")
        if traced is not None:
            self.traced[name] = grown(traced, tracemalloc.take_snapshot())
        end = self.sample(name, cycles)
        rows = [r for r in self.samples if r["phase"] == name]
        after = [r for r in rows if r["cycle"] >= warm]
        base = after[0]["rss_mb"] if after else start["rss_mb"]
        growth = end["rss_mb"] - base
        x = np.array([r["cycle"] for r in after], dtype=float)
        y = np.array([r["rss_mb"] for r in after])
        slope = float(np.polyfit(x, y, 1)[0]) if len(after) >= 3 and np.ptp(x) > 0 else 0.0
        rise = slope * (x.max() - x.min()) if len(after) >= 3 else 0.0
        self.phases[name] = {
            "cycles": cycles, "seconds": round(time.perf_counter() - t, 1), "errors": errors,
            "rss_start_mb": round(start["rss_mb"], 1), "rss_warm_mb": round(base, 1),
            "rss_end_mb": round(end["rss_mb"], 1), "growth_mb": round(growth, 1),
            "trend_mb_per_1000": round(1000 * slope, 2), "trend_rise_mb": round(rise, 1),
            "gl_before": ref_gl, "gl_after": end["gl"],
            "stale_contexts": end["stale_contexts"] - start["stale_contexts"],
        }
        if not judged:
            return
        self.check(f"{name}_rss_growth_after_warmup", growth <= GROWTH_MB, f"{growth:.1f} MB (budget {GROWTH_MB})")
        own = self.phases.get(control, {}).get("trend_rise_mb", 0.0) if control else 0.0
        blender = f"; {control}, without the add-on's operations: {own:.1f} MB" if control in self.phases else ""
        self.check(f"{name}_rss_no_upward_trend", rise - max(own, 0.0) <= TREND_MB,
                   f"fitted rise {rise:.1f} MB over cycles {x.min():.0f}..{x.max():.0f} "
                   f"({1000 * slope:.2f} MB/1000){blender}")

    def live(self, cycles):
        live = addon("live")
        live.DEBOUNCE_S = 0.0          # headless: the ticks come by hand, no need to wait
        live.start(bpy.context)
        self.live_pass()

        def body(k):
            self.move()
            self.check("live_every_tick_passes", self.live_pass(), f"no pass at cycle {k}")
        self.run("live", cycles, body, step=1)
        live.stop(bpy.context)
        self.op("occ.restore")
        self.nothing_hidden("live_nothing_hidden_after_restore", "after live and Restore")

    def cull(self, cycles):
        def body(k):
            self.move(7)
            self.op("occ.cull")
            if k == 1:
                self.check("cull_hides_something", hidden()[0] > 0, "the first Cull hid nothing")
            self.op("occ.restore")
            self.nothing_hidden("cull_nothing_hidden_after_restore", f"cycle {k}")
        self.run("cull", cycles, body, step=7)

    def undo_cycles(self, name, cycles, cull):
        """An edit, undo and redo per cycle; with ``cull``, a Cull after each and a Restore."""
        objs = [o for o in bpy.data.objects if o.type == "MESH"]
        names = [o.name for o in objs[:: max(1, len(objs) // 97)]]
        self.view = self.path.n // 2                     # mid-path: a view that hides much of the city
        self.move(0)
        bpy.ops.ed.undo_push(message=f"{name} start")     # a step to go back to from the first cycle

        def body(k):
            ob = bpy.data.objects[names[k % len(names)]]
            ob.location.z += 1e-3
            bpy.context.view_layer.update()
            bpy.ops.ed.undo_push(message=f"{name} move {k}")
            cull()
            self.op("ed.undo")
            cull()
            self.op("ed.redo")
            cull()
            if cull is not nothing:
                self.op("occ.restore")
                self.nothing_hidden("undo_nothing_hidden_after_restore", f"cycle {k}")
        if cull is nothing:
            self.run(name, cycles, body, judged=False)
        else:
            self.run(name, cycles, body, control="undo_control")

    def undo_control(self, cycles):
        self.undo_cycles("undo_control", cycles, nothing)

    def undo(self, cycles):
        self.undo_cycles("undo", cycles, lambda: self.op("occ.cull"))

    def disabled_state(self, k):
        """A disabled add-on leaves nothing: no handler, timer, draw handler, thread,
        class, property, live GL object; nothing hidden, no record."""
        reg = registrations()
        alive, _ = gl_census()
        left = {key: reg[key] for key in ("addon_handlers", "draw_handlers", "engine_alive", "engine_threads",
                                          "classes", "scene_props") if reg[key]}
        left.update({f"timer {n}": True for n, on in reg["timers"].items() if on})
        if alive:
            left["gl"] = alive
        self.check("toggle_disable_leaves_nothing", not left, f"cycle {k}: {left}")
        self.nothing_hidden("toggle_nothing_hidden_after_disable", f"cycle {k}")

    def toggle(self, cycles):
        live = addon("live")

        def body(k):
            self.move(5)
            live.start(bpy.context)
            self.live_pass()
            bpy.ops.preferences.addon_disable(module=MOD)
            self.disabled_state(k)
            bpy.ops.preferences.addon_enable(module=MOD)
            live.DEBOUNCE_S = 0.0
            self.op("occ.cull")
            self.op("occ.restore")
            self.nothing_hidden("toggle_nothing_hidden_after_restore", f"cycle {k}")
        self.run("toggle", cycles, body, step=5)

    def control(self, cycles):
        bpy.ops.extensions.package_install_files(filepath=trivial_zip(self.work), repo="user_default",
                                                 enable_on_install=True)

        def body(k):
            bpy.ops.preferences.addon_disable(module=TRIVIAL)
            bpy.ops.preferences.addon_enable(module=TRIVIAL)
        self.run("control", cycles, body)
        bpy.ops.preferences.addon_disable(module=TRIVIAL)

    def save(self, cycles):
        path = os.path.join(self.work, "soak.blend")

        def body(k):
            self.move(11)
            self.op("occ.cull")
            before = hidden()
            self.op("wm.save_as_mainfile", filepath=path)
            self.check("save_keeps_hiding", hidden() == before, f"cycle {k}: {before} -> {hidden()}")
            self.op("wm.open_mainfile", filepath=path)
            self.nothing_hidden("save_nothing_hidden_after_reload", f"cycle {k}")
            self.check("save_reload_live_off", not bpy.context.scene.occ.live, f"cycle {k}")
            self.op("occ.cull")
            self.op("occ.restore")
            self.nothing_hidden("save_nothing_hidden_after_restore", f"cycle {k}")
        self.run("save", cycles, body, step=11)


# --- report ------------------------------------------------------------------------
def grown(before, after, top=12):
    """The Python allocation sites (numpy's arrays included) that grew most between two
    ``tracemalloc`` snapshots: ``[(KB, count, "file:line"), ...]``."""
    stats = after.compare_to(before, "lineno")
    return [(round(s.size_diff / 1024, 1), s.count_diff, f"{s.traceback[0].filename}:{s.traceback[0].lineno}")
            for s in sorted(stats, key=lambda s: -s.size_diff)[:top] if s.size_diff > 0]


def table(rows, cols):
    widths = [max(len(c), *(len(str(r.get(c, ""))) for r in rows)) for c in cols]
    lines = ["  ".join(c.rjust(w) for c, w in zip(cols, widths, strict=True))]
    lines += ["  ".join(str(r.get(c, "")).rjust(w) for c, w in zip(cols, widths, strict=True)) for r in rows]
    return "\n".join(lines)


def report(out):
    phases = [{"phase": n, **{k: v for k, v in p.items() if not k.startswith("gl_")},
               "gl": sum((p["gl_after"] or {}).values())} for n, p in out["phases"].items()]
    print("\nphases (memory in MB; warm: after warm-up; rise: of a line fitted after it; "
          "undo_control: reported, not a target)")
    print(table(phases, ["phase", "cycles", "seconds", "errors", "rss_start_mb", "rss_warm_mb", "rss_end_mb",
                         "growth_mb", "trend_rise_mb", "trend_mb_per_1000", "gl", "stale_contexts"]))
    rows = [{**r, "rss": f"{r['rss_mb']:.0f}", "handlers": sum(r["handlers"].values()),
             "timers": sum(r["timers"].values()), "engine": f"{'up' if r['engine_alive'] else 'down'}/"
             f"{r['engine_queue']}"} for r in out["samples"]]
    print("\ntimeline")
    print(table(rows, ["phase", "cycle", "t", "rss", "gl_alive", "contexts", "stale_contexts", "handlers",
                       "addon_handlers", "timers", "draw_handlers", "engine", "engine_threads", "threads", "fds",
                       "hidden", "records", "tracebacks"]))
    print("\ntargets")
    for name, (ok, detail) in out["checks"].items():
        print(f"  {'ok  ' if ok else 'FAIL'} {name}" + ("" if ok or not detail else f": {detail[:300]}"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="city")
    ap.add_argument("--small", action="store_true", help="the scene's small variant")
    ap.add_argument("--scale", type=float, default=1.0, help="every count times this (at least 3 each)")
    ap.add_argument("--only", help="comma-separated phases, in this order: " + ",".join(SIZES))
    ap.add_argument("--count", action="append", default=[], metavar="PHASE=N",
                    help="this phase's count instead of the scaled one (repeatable)")
    ap.add_argument("--without-thread-release", action="store_true",
                    help="the engine thread ends without releasing its EGL state (the leak before the fix)")
    ap.add_argument("--json", help="write the summary and every sample here")
    ap.add_argument("--trace-malloc", action="store_true",
                    help="trace Python's allocations (numpy's too): per phase, the sites that grew after warm-up")
    ap.add_argument("--work", help="folder for the user resources, the zips and the saved file")
    args = ap.parse_args(argv)
    global TRACE
    TRACE = args.trace_malloc
    if TRACE:
        tracemalloc.start(1)
    work = WORK or args.work or tempfile.mkdtemp(prefix="occ_soak_")
    tee = Tee(sys.stderr)
    sys.stderr = tee
    bpy.ops.extensions.package_install_files(filepath=plain_zip(os.path.join(work, "dist")), repo="user_default",
                                             enable_on_install=True)
    objects, triangles, path = build(args.scene, args.small)
    soak = Soak(path, work, tee)
    soak.t0 = time.perf_counter()
    soak.sample("start", 0)
    chosen = args.only.split(",") if args.only else list(SIZES)
    unknown = set(chosen) - set(SIZES)
    if unknown:
        ap.error(f"unknown phases {sorted(unknown)}; choose from {', '.join(SIZES)}")
    counts = {n: max(3, round(SIZES[n] * args.scale)) for n in SIZES if n in chosen}
    for item in args.count:
        name, _, n = item.partition("=")
        if name not in counts or not n.isdigit():
            ap.error(f"--count {item}: expected PHASE=N with PHASE one of {', '.join(counts)}")
        counts[name] = int(n)
    if args.without_thread_release:
        sys.modules[f"{MOD}.occ_addon.worker"].release_thread_gl = lambda: None
    for name in SIZES:
        if name in counts:
            getattr(soak, name)(counts[name])
    soak.check("no_traceback_printed", not tee.lines, tee.lines[:10])
    out = {"scene": args.scene + ("-small" if args.small else ""), "objects": objects, "triangles": triangles,
           "blender": bpy.app.version_string, "scale": args.scale, "counts": counts,
           "thread_release": not args.without_thread_release,
           "seconds": round(time.perf_counter() - soak.t0, 1), "phases": soak.phases, "checks": soak.checks,
           "tracebacks": tee.lines[:50], "samples": soak.samples, "malloc_grown": soak.traced}
    print(f"\n{out['scene']}: {objects:,} objects, {triangles:,} triangles, Blender {out['blender']}, "
          f"{out['seconds']:.0f} s")
    report(out)
    for phase, sites in soak.traced.items():
        print(f"\n{phase}: Python allocations grown after warm-up (KB, count, site)")
        for kb, count, site in sites:
            print(f"  {kb:10.1f} {count:7d}  {site}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    failed = [n for n, (ok, _) in soak.checks.items() if not ok]
    print(f"\n{len(failed)} of {len(soak.checks)} targets failed" + (f": {', '.join(failed)}" if failed else ""))
    sys.stderr = tee.stream
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
