"""What hiding costs Blender itself, without the add-on: plain bpy, N objects.

    .venv/bin/python tools/bench/blender_hide_cost.py [--objects 50000] [--repeat 3] [--by-view-size]

Builds N one-triangle objects sharing one mesh, then times the depsgraph
update (``view_layer.update()``) that follows each kind of visibility change
Blender offers to Python, median of ``--repeat``:

- nothing changed (the update's floor);
- ``hide_viewport`` (the monitor icon, what the add-on writes) of ONE object;
- ``hide_viewport`` of a third of the objects (one ``foreach_set`` and one
  ordinary assignment, as the add-on writes it), then all shown again;
- ``hide_set`` (the eye: the user's own per-view-layer hide) of one object,
  and of 1,000 objects one call each (every call re-syncs the view layer);
- a 3D view's local-view bit (``local_view_set``, what the add-on writes to hide in
  one view) of one object, and of a third of the objects, one call each, and back.

Any of these is a cost a culling pass pays on top of its own work whenever
what it hides changes; docs/performance.md's "Blender at scale" section quotes it.
"""

import argparse
import statistics
import time

import bpy
import numpy as np


def build(n):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    me = bpy.data.meshes.new("tri")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    link = bpy.context.scene.collection.objects.link
    for i in range(n):
        ob = bpy.data.objects.new(f"o{i}", me)
        ob.location = (i % 250, i // 250, 0)
        link(ob)
    bpy.context.view_layer.update()


def _view():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    return win, area, next(r for r in area.regions if r.type == "WINDOW")


def local_view(items):
    """The window's 3D view in local view holding every object (as the add-on's own):
    its ``SpaceView3D``."""
    win, area, region = _view()
    items[0].select_set(True)
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.view3d.localview(frame_selected=False)
    items[0].select_set(False)
    space = area.spaces.active
    for o in items:
        o.local_view_set(space, True)
    bpy.context.view_layer.update()
    return space


def leave_local_view():
    win, area, region = _view()
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.view3d.localview(frame_selected=False)
    bpy.context.view_layer.update()


def timed_update():
    t = time.perf_counter()
    bpy.context.view_layer.update()
    return time.perf_counter() - t


def by_view_size(n, repeat):
    """The update after one local-view bit, with all, a third and a twenty-fifth of the
    objects in the view's local view, and after selecting one object: what the base
    update costs grows with the view layer's objects or with those the view shows."""
    items = bpy.data.objects.values()
    space = local_view(items)
    print(f"{'change, then view_layer.update()':58s} {'median s':>9s} {'max s':>7s}")
    for k in (n, n // 3, n // 25):
        for o in items[k:]:
            o.local_view_set(space, False)
        bpy.context.view_layer.update()
        times, selects = [], []
        for r in range(repeat):
            items[0].local_view_set(space, r % 2 == 1)
            times.append(timed_update())
            items[1].select_set(r % 2 == 0)
            selects.append(timed_update())
        items[0].local_view_set(space, True)
        items[1].select_set(False)
        bpy.context.view_layer.update()
        for label, v in ((f"local-view bit, one object ({k:,} of {n:,} in the view)", times),
                         (f"selection of one object ({k:,} in the view)", selects)):
            print(f"{label:58s} {statistics.median(v):9.3f} {max(v):7.3f}")
    leave_local_view()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=50_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--by-view-size", action="store_true",
                    help="only: one local-view bit's update with fewer objects in the view, and a selection's")
    args = ap.parse_args()
    n = args.objects
    t = time.perf_counter()
    build(n)
    print(f"{n:,} objects built in {time.perf_counter() - t:.1f} s (bpy {bpy.app.version_string})")
    if args.by_view_size:
        by_view_size(n, args.repeat)
        return
    objs = bpy.data.objects
    third = np.zeros(n, dtype=bool)
    third[::3] = True
    rows = {k: [] for k in ("nothing changed", "hide_viewport, one object",
                            f"hide_viewport, {third.sum():,} objects", f"show those {third.sum():,} again",
                            "hide_set, one object", "hide_set, 1,000 objects (calls + update)",
                            "local-view bit, one object (in a view's local view)",
                            f"local-view bits, {third.sum():,} objects (calls + update)",
                            f"local-view bits of those {third.sum():,} back (calls + update)")}
    keys = list(rows)
    items = objs.values()
    for _ in range(args.repeat):
        rows[keys[0]].append(timed_update())
        ob = items[n // 2]
        ob.hide_viewport = not ob.hide_viewport
        rows[keys[1]].append(timed_update())
        ob.hide_viewport = False
        bpy.context.view_layer.update()
        objs.foreach_set("hide_viewport", third)
        items[0].hide_viewport = True                 # the ordinary assignment: bases re-synced
        rows[keys[2]].append(timed_update())
        objs.foreach_set("hide_viewport", np.zeros(n, dtype=bool))
        items[0].hide_viewport = False
        rows[keys[3]].append(timed_update())
        ob.hide_set(True)
        rows[keys[4]].append(timed_update())
        ob.hide_set(False)
        bpy.context.view_layer.update()
        t = time.perf_counter()
        for o in items[:1000]:
            o.hide_set(True)
        bpy.context.view_layer.update()
        rows[keys[5]].append(time.perf_counter() - t)
        for o in items[:1000]:
            o.hide_set(False)
        bpy.context.view_layer.update()
        space = local_view(items)
        ob.local_view_set(space, False)
        rows[keys[6]].append(timed_update())
        ob.local_view_set(space, True)
        bpy.context.view_layer.update()
        for state, key in ((False, keys[7]), (True, keys[8])):
            t = time.perf_counter()
            for i in np.flatnonzero(third):
                items[i].local_view_set(space, state)
            bpy.context.view_layer.update()
            rows[key].append(time.perf_counter() - t)
        leave_local_view()
    print(f"{'change, then view_layer.update()':58s} {'median s':>9s} {'max s':>7s}")
    for k, v in rows.items():
        print(f"{k:58s} {statistics.median(v):9.3f} {max(v):7.3f}")


if __name__ == "__main__":
    main()
