"""Time the add-on's live cull pass headless, with ``bpy`` from PyPI:

    .venv/bin/python tools/bench/live_pass.py [SCENE] [--frames N] [--json OUT]

Registers the add-on from this checkout, builds SCENE (default ``city``) as
Blender objects, runs one pass from the first camera of its path (the engine is
built), then times ``Session.cull`` along the path the way live mode calls it
(the view moved, nothing else changed; ``--envelope rest``: with the envelope live
mode gives a pass at rest; ``--after-edit``: one object moved too, and
the pass fresh, as live mode does after a scene change; ``--strategy`` sets the
add-on's strategy):
the whole pass and its parts, from the pass's own figures (``Session.last``): the
engine's pass (``PassStats.total_ms``), Blender's updates (``LastPass.blender_ms``)
and the rest, the add-on's reads, policy and writes.  ``--hide-in`` picks the
channel: VIEW (default) is what live mode uses in a window.  The goal in
the add-on's issue is one pass in 50 ms or less for 2,000 objects.
"""

import argparse
import json
import os
import sys
import tempfile
import time

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tools"))
from blender_scene import build_scene  # noqa: E402

PKG = "occlusion_culled_viewport"
DISPLAY = (1280, 720)


def load_addon():
    """This checkout as the add-on package (the name an extension install would give)."""
    link_dir = tempfile.mkdtemp(prefix="occ_live_")
    os.symlink(ROOT, os.path.join(link_dir, PKG))
    sys.path.insert(0, link_dir)
    import importlib
    addon = importlib.import_module(PKG)
    addon.register()
    return addon


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="city")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--objects", type=int, help="keep only the first N objects of the scene")
    ap.add_argument("--strategy", help="the add-on's strategy setting (default: the add-on's default)")
    ap.add_argument("--after-edit", action="store_true",
                    help="before each pass move one object a little and pass fresh, as live mode does "
                         "after any scene change")
    ap.add_argument("--envelope", help="'rest' (what live mode makes at rest) or D,A (a pass during motion): "
                                       "the pass hides only what stays hidden while the view moves that far")
    ap.add_argument("--hide-in", default="VIEW", choices=("VIEW", "EVERYWHERE"),
                    help="where the pass hides: VIEW (default; what live mode does in a window: the 3D view's "
                         "local-view bits) or EVERYWHERE (hide_viewport, what Auto gives in background mode)")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    addon = load_addon()
    core = sys.modules[f"{PKG}.core"]
    session = sys.modules[f"{PKG}.occ_addon.session"]
    import sample_scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = core.load_scene(str(sample_scenes.scene_path(args.scene)))
    build_scene(scene, limit=args.objects)
    bpy.context.view_layer.update()
    cams = core.camera.cameras_from_json(sample_scenes.default_camera_path(args.scene))
    cams = [cams[i] for i in np.linspace(0, len(cams) - 1, min(args.frames, len(cams))).round().astype(int)]
    sess = session.SESSION
    ctx = bpy.context
    envelope = args.envelope
    if envelope == "rest":
        envelope = core.motion.AT_REST
    elif envelope is not None:
        envelope = core.envelope.Envelope.parse(envelope)
    if args.strategy:
        ctx.scene.occ.strategy = args.strategy
    ctx.scene.occ.hide_in = args.hide_in
    t = time.perf_counter()
    sess.cull(ctx, cams[0], DISPLAY, envelope=envelope)
    first = 1e3 * (time.perf_counter() - t)
    engine = sess.culler
    rows = []
    movable = [o for o in ctx.scene.objects if o.type == "MESH"]
    rng = np.random.default_rng(0)
    for cam in cams[1:]:
        if args.after_edit:
            ob = movable[int(rng.integers(len(movable)))]
            ob.location.z += 1e-3
            ctx.view_layer.update()
        t0 = time.perf_counter()
        sess.cull(ctx, cam, DISPLAY, fresh=args.after_edit, envelope=envelope)
        t1 = time.perf_counter()
        last = sess.last                   # the pass's own figures: no second pass to compare
        engine_ms = last.stats.total_ms
        rows.append([1e3 * (t1 - t0), last.blender_ms, engine_ms,
                     1e3 * (t1 - t0) - last.blender_ms - engine_ms, last.changed])
    rows = np.array(rows)
    med = np.median(rows, axis=0)
    n = len(scene) if args.objects is None else min(args.objects, len(scene))
    out = {"scene": args.scene, "strategy": ctx.scene.occ.strategy, "after_edit": args.after_edit,
           "envelope": args.envelope, "hide_in": args.hide_in,
           "objects": n, "triangles": int(scene.triangle_counts[:n].sum()),
           "display": DISPLAY, "blender": bpy.app.version_string, "first_pass_ms": first,
           "passes": len(rows), "pass_ms_median": med[0], "pass_ms_p95": float(np.percentile(rows[:, 0], 95)),
           "blender_update_ms_median": med[1], "engine_ms_median": med[2], "addon_ms_median": med[3],
           "changed_median": med[4], "engine_rebuilt": sess.culler is not engine}
    print(f"{args.scene}: {out['objects']} objects, {out['triangles']:,} triangles, Blender {out['blender']}, "
          f"strategy {out['strategy']}, hiding in {args.hide_in}"
          + (", a move before each pass" if args.after_edit else ""))
    print(f"first pass (extract + build) {first:.0f} ms; live pass median {med[0]:.1f} ms "
          f"(p95 {out['pass_ms_p95']:.1f}) over {len(rows)} views, medians of its parts: engine {med[2]:.1f}, "
          f"Blender's updates {med[1]:.1f}, the add-on's reads, policy and writes {med[3]:.1f} ms; "
          f"{med[4]:.0f} objects changed; engine rebuilt: {out['engine_rebuilt']}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({k: (float(v) if isinstance(v, np.floating) else v) for k, v in out.items()}, f, indent=1)
    sess.shutdown()
    addon.unregister()


if __name__ == "__main__":
    main()
