"""Command line: ``python -m core cull | truth | bench | tradeoff | demo``.

Output shapes are the contract of DESIGN.md; every user error is an
:class:`OccError` printed as one line on stderr with exit status 2.
"""

import argparse
import json
import os
import sys

from .camera import cameras_from_json, load_cameras
from .engine import DEFAULT_RESOLUTION, Culler, parse_resolution
from .errors import OccError
from .scene import load_scene
from .strategies import DEFAULT_STRATEGY, STRATEGIES

EXIT_USER_ERROR = 2


def resolve_scene(spec):
    """A scene file path, or the name of a bundled sample scene -> (path, sample name or None)."""
    if os.path.exists(spec):
        return spec, None
    try:
        import sample_scenes
        names = tuple(sample_scenes.NAMES)
    except (ImportError, AttributeError):
        names = ()
    base, small, joined = spec, False, False
    if base.endswith("-joined"):
        base, joined = base[:-7], True
    if base.endswith("-small"):
        base, small = base[:-6], True
    if base in names:
        return str(sample_scenes.scene_path(base, small=small, joined=joined)), base
    hint = (f" (or a sample scene: {', '.join(names)}; -small for the small variant, -joined for "
            "all objects merged into one mesh)" if names else "")
    raise OccError(f"scene file not found: {spec}{hint}")


def resolve_cameras(camera_arg, sample_name):
    if camera_arg:
        return load_cameras(camera_arg)
    if sample_name is None:
        raise OccError("--camera CAM.json is required for a scene file")
    import sample_scenes
    return cameras_from_json(sample_scenes.default_camera_path(sample_name))


def spread(items, k):
    """At most ``k`` items, evenly spread over the list (all of them when k is falsy)."""
    if not k:
        return items
    return items[:: max(1, len(items) // k)][:k]


def load_job(scene_spec, camera_arg, frames=None):
    """Scene, cameras (at most ``frames`` of them, evenly spread) and a title for reports."""
    path, sample = resolve_scene(scene_spec)
    cameras = spread(resolve_cameras(camera_arg, sample), frames)
    title = scene_spec if sample else os.path.splitext(os.path.basename(path))[0]
    return load_scene(path), cameras, title


def log_for(as_json):
    """Progress goes to stderr when stdout carries JSON."""
    return (lambda *a: print(*a, file=sys.stderr)) if as_json else print


def _frames(culler, cameras, names_of, run):
    out = []
    for cam in cameras:
        visible, stats = run(culler, cam)
        out.append({"visible": names_of(visible), "stats": stats})
    return out


def cmd_cull(args):
    path, sample = resolve_scene(args.scene)
    cameras = resolve_cameras(args.camera, sample)
    scene = load_scene(path)
    with Culler(scene, parse_resolution(args.resolution), strategy=args.strategy) as culler:
        def run(c, cam):
            r = c.cull(cam)
            return r.visible, r.stats
        frames = _frames(culler, cameras, lambda m: [scene.names[i] for i in m.nonzero()[0]], run)
    _print_frames(frames, args.json)


def cmd_truth(args):
    path, sample = resolve_scene(args.scene)
    cameras = resolve_cameras(args.camera, sample)
    scene = load_scene(path)
    with Culler(scene, parse_resolution(args.resolution), strategy="vfc") as culler:
        def run(c, cam):
            t = c.truth(cam)
            return t, {"objects": len(t), "visible": int(t.sum())}
        frames = _frames(culler, cameras, lambda m: [scene.names[i] for i in m.nonzero()[0]], run)
    _print_frames(frames, args.json)


def _print_frames(frames, as_json):
    if as_json:
        json.dump({"frames": frames}, sys.stdout)
        sys.stdout.write("\n")
        return
    for i, f in enumerate(frames):
        s = f["stats"]
        extra = "".join(f", {k} {s[k]}" for k in ("occluded", "view_culled", "queries",
                                                   "triangles_drawn") if k in s)
        ms = f", {s['total_ms']:.1f} ms" if "total_ms" in s else ""
        print(f"frame {i}: {len(f['visible'])} of {s['objects']} visible{extra}{ms}")


def build_parser():
    p = argparse.ArgumentParser(prog="python -m core", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    res = f"{DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]}"

    c = sub.add_parser("cull", help="visible objects per camera frame")
    c.add_argument("scene", help="scene file (glTF/GLB, OBJ, PLY, ...) or a sample scene name")
    c.add_argument("--camera", help="camera JSON (one camera or {\"frames\": [...]})")
    c.add_argument("--strategy", default=DEFAULT_STRATEGY, choices=STRATEGIES)
    c.add_argument("--resolution", default=res, help=f"query resolution WxH (default {res})")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=cmd_cull)

    t = sub.add_parser("truth", help="exact visible set from an object-ID buffer")
    t.add_argument("scene")
    t.add_argument("--camera")
    t.add_argument("--resolution", default=res)
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=cmd_truth)

    from . import bench, tradeoff
    bench.add_commands(sub)
    tradeoff.add_commands(sub)
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except OccError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USER_ERROR
    return 0
