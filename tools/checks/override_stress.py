"""Another add-on's operators, called from its timer through ``bpy.context.temp_override``,
while the add-on's engine thread builds and culls (real bpy, headless), issue 30:

    .venv/bin/python tools/checks/override_stress.py [--runs 3] [--cycles 40] [--objects 20000]
                                              [--minutes M] [--json OUT]

Each run is a process of its own (a crash ends one run and is counted, rc and the
stack ``faulthandler`` printed).  A run installs the extension as a user does, builds
``tools/bench/blender_scale.py``'s rows of cubes behind a wall (``--objects``; the scene
camera, Hide In: This View, so the add-on hides in its own local view of the file's 3D
view), culls once, then per cycle: adds a cube (the engine must be rebuilt) and drives
the steps a window's modal operator drives from its timer events (``Stepped.modal``):
the first Cull's (``Session.prepare_steps``: extraction on the main thread, the build a
``Job`` on the engine thread), and, every third cycle, an analysis's
(``analysis_steps``: a cull ``Job`` per frame); every fourth build is cancelled midway
(Esc: the steps closed).  Between two steps, and over and over while a job runs, the
foreign timer fires: it is registered with ``bpy.app.timers.register`` as any add-on
does, and called here because headless Blender runs no event loop (no timer fires by
itself).  Each call runs the next few of a rotation of common operators, each under
``temp_override``: ``view3d.*`` and ``outliner.*`` with the file's window, area and
region; ``object.*`` (select_all, duplicate, transform_apply, origin_set, shade_smooth,
modifier_add/apply, convert, delete) and edit-mode ``mesh.*`` with the objects
overridden; ``ed.undo_push``; ``wm.save_as_mainfile(copy=True)``.  Then the Cull's last
step (``occ.cull``) and every other cycle ``occ.restore``.

What it covers: the operators run on Blender's main thread while the engine thread
runs Python (the build, a cull): Blender 4.2 and 5.0 read a ``temp_override``'s
dictionary without Python's lock there and crash when another Python thread runs
(``tools/repro/override_thread_crash.py``, no add-on).  The add-on's guard on ``bpy.ops``
(``worker._OperatorGuard``) makes every such call wait for the engine's job, so the
``during`` counts are 0; no crash in N calls is evidence, not proof.  It does not
cover a real window's event loop (timers and modal handlers interleaved by Blender,
redraws, draw handlers): no Blender binary or X server here.  Prints, per operator,
calls, calls made while a job ran (``during``: not done before the call and not
after), outcomes; per run: rc, crash stack; ``--json`` writes it all.  Exits 1 on a
crash or an add-on failure.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MARK = "OCC_STRESS "
EXT_ID = "occlusion_culled_viewport"
MOD = f"bl_ext.user_default.{EXT_ID}"
DISPLAY = (1280, 720)


# --- the child: one run in Blender ------------------------------------------------
def child(args):
    import bpy
    import numpy as np
    sys.path[:0] = [os.path.join(ROOT, "tools"), os.path.join(ROOT, "tools", "bench")]
    from blender_scale import build_rows
    from build_extension import plain_zip

    work = args.work
    if not args.no_addon:
        bpy.ops.extensions.package_install_files(filepath=plain_zip(os.path.join(work, "dist")),
                                                 repo="user_default", enable_on_install=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    build_rows(bpy, args.objects, unique=False)
    scene = bpy.context.scene
    if not args.no_addon:
        scene.occ.source, scene.occ.hide_in = "CAMERA", "VIEW"
    scene.frame_start, scene.frame_end = 1, 3
    bpy.context.view_layer.update()
    if not args.no_addon:
        session = sys.modules[f"{MOD}.occ_addon.session"].SESSION
        worker = sys.modules[f"{MOD}.occ_addon.worker"]
        analysis = sys.modules[f"{MOD}.occ_addon.analysis"]
    win = bpy.context.window_manager.windows[0]
    areas = {a.type: a for a in win.screen.areas}
    region = {t: next(r for r in a.regions if r.type == "WINDOW") for t, a in areas.items()}
    stats, state = {}, {"job": None, "dup": None, "k": 0}
    rng = np.random.default_rng(args.seed)

    def over(kind, **kw):
        if kind in ("VIEW_3D", "OUTLINER"):
            return bpy.context.temp_override(window=win, area=areas[kind], region=region[kind], **kw)
        return bpy.context.temp_override(window=win, **kw)

    def target():
        """The foreign add-on's own object (a duplicate it made), else a new one."""
        ob = state["dup"]
        if ob is None or ob.name not in bpy.data.objects:
            src = bpy.data.objects["cube000000"]
            with over(None, selected_objects=[src], selected_editable_objects=[src], active_object=src,
                      object=src):
                bpy.ops.object.duplicate()
            ob = state["dup"] = bpy.context.view_layer.objects.active
            if ob is None or ob.name == src.name:      # duplicate selects the copy; else make one
                ob = state["dup"] = bpy.data.objects.new("foreign", src.data.copy())
                scene.collection.objects.link(ob)
        return ob

    def objects_op(call):
        def run():
            ob = target()
            with over(None, selected_objects=[ob], selected_editable_objects=[ob], active_object=ob, object=ob):
                return call(ob)
        return run

    def delete(ob):
        r = bpy.ops.object.delete()
        state["dup"] = None
        return r

    def edit(ob):
        bpy.context.view_layer.objects.active = ob        # edit mode follows the view layer's active object
        bpy.ops.object.mode_set(mode="EDIT")
        try:
            with bpy.context.temp_override(edit_object=ob):
                bpy.ops.mesh.select_all(action="SELECT")
                return bpy.ops.mesh.subdivide()
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")

    def modifier(ob):
        bpy.ops.object.modifier_add(type="BEVEL")
        return bpy.ops.object.modifier_apply(modifier=ob.modifiers[-1].name)

    def save():
        with over(None):
            return bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, "foreign.blend"), copy=True)

    def view(op, **kw):
        def run():
            with over("VIEW_3D"):
                return op(**kw)
        return run

    def outliner(op, **kw):
        def run():
            with over("OUTLINER"):
                return op(**kw)
        return run

    ops = [
        ("view3d.view_axis", view(bpy.ops.view3d.view_axis, type="TOP")),
        ("view3d.view_all", view(bpy.ops.view3d.view_all)),
        ("object.select_all", _select_all(bpy, over)),
        ("object.duplicate", objects_op(lambda ob: bpy.ops.object.duplicate())),
        ("object.transform_apply", objects_op(lambda ob: bpy.ops.object.transform_apply(location=False))),
        ("outliner.select_all", outliner(bpy.ops.outliner.select_all, action="SELECT")),
        ("object.origin_set", objects_op(lambda ob: bpy.ops.object.origin_set(type="ORIGIN_GEOMETRY"))),
        ("object.shade_smooth", objects_op(lambda ob: bpy.ops.object.shade_smooth())),
        ("view3d.view_selected", view(bpy.ops.view3d.view_selected)),
        ("mesh.subdivide (edit mode)", objects_op(edit)),
        ("object.modifier_apply", objects_op(modifier)),
        ("outliner.expanded_toggle", outliner(bpy.ops.outliner.expanded_toggle)),
        ("object.convert", objects_op(lambda ob: bpy.ops.object.convert(target="MESH"))),
        ("ed.undo_push", lambda: bpy.ops.ed.undo_push(message="foreign")),
        ("view3d.snap_cursor_to_selected", view(bpy.ops.view3d.snap_cursor_to_selected)),
        ("object.delete", objects_op(delete)),
        ("wm.save_as_mainfile(copy)", save),
    ]
    def foreign_timer():
        """Another add-on's timer: the next operators of the rotation, each overridden."""
        for _ in range(args.per_call):
            name, call = ops[state["k"] % len(ops)]
            state["k"] += 1
            if name.startswith("wm.save") and rng.random() > 0.2:
                continue                                 # saves are slow: one turn in five
            job = state["job"]
            busy = job is not None and not job.done()
            s = stats.setdefault(name, {"calls": 0, "during": 0, "FINISHED": 0, "CANCELLED": 0, "error": 0,
                                        "last_error": ""})
            s["calls"] += 1
            try:
                r = call()
                key = "FINISHED" if "FINISHED" in r else "CANCELLED"
                s[key] += 1
            except Exception as e:  # poll failures and the like: an outcome, not a crash
                s["error"] += 1
                s["last_error"] = f"{type(e).__name__}: {e}"[:200]
            s["during"] += busy and job is not None and not job.done()
        return 0.01

    bpy.app.timers.register(foreign_timer, first_interval=0.01, persistent=True)

    def drive(steps, cancel_at=None):
        """The modal operator's loop: a step per timer event, the foreign timer between
        steps and, while a job runs, again and again.  ``cancel_at``: Esc at that job."""
        jobs = 0
        try:
            while True:
                item = next(steps)
                if isinstance(item, worker.Job):
                    jobs += 1
                    state["job"] = item
                    if cancel_at is not None and jobs == cancel_at:
                        foreign_timer()
                        steps.close()
                        return "cancelled"
                    while not item.done():
                        foreign_timer()
                    state["job"] = None
                else:
                    foreign_timer()
        except StopIteration as stop:
            return stop.value
        finally:
            state["job"] = None

    out = {"objects": args.objects, "cycles": 0, "failures": [], "ops": stats, "builds": 0, "analyses": 0,
           "cancelled": 0, "timer_registered": bpy.app.timers.is_registered(foreign_timer)}
    if args.no_addon:            # the control: the same foreign operators, no add-on, as long
        t0 = time.perf_counter()
        for k in range(args.cycles):
            if args.minutes and time.perf_counter() - t0 > 60 * args.minutes:
                break
            print(f"CYCLE {k}", flush=True)
            for _ in range(40):
                foreign_timer()
            out["cycles"] = k + 1
        bpy.app.timers.unregister(foreign_timer)
        print(MARK + json.dumps(out), flush=True)
        return
    first = bpy.ops.occ.cull()
    out["first_cull"] = sorted(first)
    t0 = time.perf_counter()
    for k in range(args.cycles):
        if args.minutes and time.perf_counter() - t0 > 60 * args.minutes:
            break
        print(f"CYCLE {k}", flush=True)
        extra = bpy.data.objects.new(f"extra{k}", bpy.data.meshes["cube"])
        scene.collection.objects.link(extra)
        extra.location = (5.0 + k, 0.0, 0.5)
        bpy.context.view_layer.update()
        try:
            session.busy = "cull"
            try:
                cancel = 1 if k % 4 == 3 else None
                r = drive(session.prepare_steps(bpy.context, DISPLAY), cancel)
                out["cancelled" if r == "cancelled" else "builds"] += 1
            finally:
                session.busy = None
            r = bpy.ops.occ.cull()
            if "FINISHED" not in r:
                out["failures"].append(f"cycle {k}: occ.cull {r}")
            if k % 3 == 2:
                session.busy = "analyze"
                try:
                    path = os.path.join(work, f"report{k}.json")
                    drive(analysis.analysis_steps(bpy.context, [1, 2, 3], path, "seen", 1))
                    out["analyses"] += 1
                finally:
                    session.busy = None
            if k % 2 == 1:
                bpy.ops.occ.restore()
        except Exception:  # the add-on's (or this tool's) failure: recorded, the run goes on
            out["failures"].append(f"cycle {k}: {traceback.format_exc()[-1500:]}")
        out["cycles"] = k + 1
    bpy.app.timers.unregister(foreign_timer)
    bpy.ops.occ.restore()
    print(MARK + json.dumps(out), flush=True)


def _select_all(bpy, over):
    def run():
        with over(None, view_layer=bpy.context.view_layer):
            return bpy.ops.object.select_all(action="DESELECT" if bpy.context.selected_objects else "SELECT")
    return run


# --- the parent: runs, each in a process ---------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cycles", type=int, default=40, help="builds per run")
    ap.add_argument("--objects", type=int, default=20_000)
    ap.add_argument("--per-call", type=int, default=3, help="operators per timer call")
    ap.add_argument("--minutes", type=float, help="stop each run's cycles after this long")
    ap.add_argument("--json")
    ap.add_argument("--no-addon", action="store_true",
                    help="the control: the same foreign operators without the extension installed")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--work", help=argparse.SUPPRESS)
    ap.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args)
        return 0
    runs, ops = [], {}
    for run in range(args.runs):
        work = tempfile.mkdtemp(prefix="occ_override_")
        env = {**os.environ, "BLENDER_USER_RESOURCES": os.path.join(work, "user"), "PYTHONFAULTHANDLER": "1"}
        cmd = [sys.executable, os.path.abspath(__file__), "--child", "--work", work, "--seed", str(run),
               "--cycles", str(args.cycles), "--objects", str(args.objects), "--per-call", str(args.per_call)]
        if args.no_addon:
            cmd.append("--no-addon")
        if args.minutes:
            cmd += ["--minutes", str(args.minutes)]
        t = time.perf_counter()
        p = subprocess.run(cmd, env=env, cwd=work, capture_output=True, text=True)
        line = next((ln for ln in p.stdout.splitlines() if ln.startswith(MARK)), None)
        result = json.loads(line[len(MARK):]) if line else {}
        cycles = [ln for ln in p.stdout.splitlines() if ln.startswith("CYCLE ")]
        row = {"run": run, "rc": p.returncode, "seconds": round(time.perf_counter() - t, 1),
               "crashed": p.returncode < 0 or p.returncode > 128, "last_cycle": cycles[-1] if cycles else None,
               **{k: v for k, v in result.items() if k != "ops"}}
        if line is None:
            row["stderr_tail"] = p.stderr[-4000:]
        runs.append(row)
        for name, s in result.get("ops", {}).items():
            total = ops.setdefault(name, {k: 0 for k in s if k != "last_error"} | {"last_error": ""})
            for key, v in s.items():
                if key != "last_error":
                    total[key] += v
                elif v:
                    total[key] = v
        print(f"run {run}: rc {p.returncode}, {row.get('cycles', 0)} cycles ({row.get('builds', 0)} builds, "
              f"{row.get('cancelled', 0)} cancelled, {row.get('analyses', 0)} analyses), "
              f"{len(row.get('failures', []))} failures, {row['seconds']:.0f} s", flush=True)
        if line is None:
            print(p.stderr[-3000:], flush=True)
    width = max(len(n) for n in ops) if ops else 10
    print(f"\n{'operator'.ljust(width)}  calls  during  FINISHED  CANCELLED  error  last error")
    for name, s in ops.items():
        print(f"{name.ljust(width)}  {s['calls']:5d}  {s['during']:6d}  {s['FINISHED']:8d}  {s['CANCELLED']:9d}  "
              f"{s['error']:5d}  {s['last_error'][:80]}")
    calls = sum(s["calls"] for s in ops.values())
    during = sum(s["during"] for s in ops.values())
    crashes = sum(r["crashed"] for r in runs)
    failures = sum(len(r.get("failures", [])) for r in runs) + sum(r.get("cycles") is None for r in runs)
    print(f"\n{len(runs)} runs, {crashes} crashed; {calls} foreign operator calls, {during} of them while "
          f"the engine thread ran a job throughout; {failures} add-on failures")
    for r in runs:
        for f in r.get("failures", [])[:3]:
            print(f"  run {r['run']}: {f[:600]}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"runs": runs, "ops": ops, "crashes": crashes, "calls": calls, "during": during}, f, indent=1)
    return 1 if crashes or failures else 0


if __name__ == "__main__":
    sys.exit(main())
