"""Plain bpy, no add-on: a Python thread that runs Python code while the main thread
calls operators through ``bpy.context.temp_override`` (issue 30's stress check):

    .venv/bin/python tools/repro/override_thread_crash.py [--runs 4] [--calls 3000] [--idle | --no-thread]

Each run is a process of its own: the main thread builds a few hundred cubes, then
calls a rotation of common operators (``object.duplicate``, ``object.delete``,
``object.select_all``, ``object.shade_smooth``, ``object.convert``), each under
``temp_override`` with objects overridden, while a plain ``threading.Thread`` builds
and drops small Python lists and dicts (what any Python code does: allocations,
reference counts); ``--idle``: the thread blocks on a queue instead (no Python runs
on it); ``--no-thread``: the control, no second thread.  Prints per run the exit
code (139 / -11: a segfault) and the calls made.
A crash here needs no add-on: Blender reads a context override's dictionary while
another Python thread runs.
"""

import argparse
import os
import subprocess
import sys
import time


def child(calls, idle):
    """``idle``: False a busy thread, True a blocked one, None no thread (the control)."""
    import queue
    import threading

    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("cube")
    mesh.from_pydata([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], [],
                     [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    for i in range(300):
        ob = bpy.data.objects.new(f"c{i}", mesh)
        ob.location = (i % 20 * 2.0, i // 20 * 2.0, 0.0)
        scene.collection.objects.link(ob)
    bpy.context.view_layer.update()
    stop = threading.Event()
    q = queue.SimpleQueue()

    def busy():
        while not stop.is_set():
            junk = [{"k": i, "v": [i] * 8} for i in range(2000)]
            del junk

    def blocked():
        q.get()

    if idle is not None:
        t = threading.Thread(target=blocked if idle else busy, daemon=True)
        t.start()
    win = bpy.context.window_manager.windows[0]
    ops = [lambda: bpy.ops.object.duplicate(), lambda: bpy.ops.object.shade_smooth(),
           lambda: bpy.ops.object.select_all(action="SELECT"), lambda: bpy.ops.object.convert(target="MESH"),
           lambda: bpy.ops.object.delete()]
    made = 0
    for k in range(calls):
        ob = bpy.data.objects[k % len(bpy.data.objects)]
        with bpy.context.temp_override(window=win, selected_objects=[ob], selected_editable_objects=[ob],
                                       active_object=ob, object=ob):
            try:
                ops[k % len(ops)]()
            except RuntimeError:
                pass
        made += 1
        if k % 500 == 0:
            print(f"CALLS {made}", flush=True)
    stop.set()
    q.put(None)
    print(f"CALLS {made} done", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--calls", type=int, default=3000)
    ap.add_argument("--idle", action="store_true", help="the thread blocks on a queue (no Python runs on it)")
    ap.add_argument("--no-thread", action="store_true", help="the control: no second thread")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.calls, None if args.no_thread else args.idle)
        return 0
    crashes = 0
    for run in range(args.runs):
        t = time.perf_counter()
        cmd = [sys.executable, os.path.abspath(__file__), "--child", "--calls", str(args.calls)]
        cmd += ["--idle"] if args.idle else ["--no-thread"] if args.no_thread else []
        p = subprocess.run(cmd, capture_output=True, text=True,
                           env={**os.environ, "PYTHONFAULTHANDLER": "1"})
        last = [ln for ln in p.stdout.splitlines() if ln.startswith("CALLS")]
        crashed = p.returncode < 0 or p.returncode > 128
        crashes += crashed
        print(f"run {run}: rc {p.returncode}, {last[-1] if last else 'no calls'}, "
              f"{time.perf_counter() - t:.0f} s", flush=True)
        if crashed:
            print("\n".join(p.stderr.splitlines()[:12]), flush=True)
    kind = "no" if args.no_thread else "an idle" if args.idle else "a busy"
    print(f"{args.runs} runs, {crashes} crashed ({kind} second thread)")
    return 1 if crashes else 0


if __name__ == "__main__":
    sys.exit(main())
