"""Command line: ``python -m core cull | truth | analyze | merge | bench | motion | tradeoff | demo``.

The command front-ends live here and only here; the work is in libraries
(:mod:`core.lab.jobs` loads a job, :mod:`core.lab.analyze` analyzes a camera path and
merges chunk reports, :mod:`core.lab.bench`, :mod:`core.lab.tradeoff` and
:mod:`core.lab.reports` measure and write).  Output shapes are the contract of
DESIGN.md; every user error is an :class:`OccError` printed as one line on
stderr with exit status 2.
"""

import argparse
import json
import math
import os
import sys

import numpy as np

from .. import DEFAULT_STRATEGY, REGISTRY, STRATEGIES, Visibility
from ..analysis import REPORT_NAME as ANALYSIS_REPORT
from ..engine import DEFAULT_RESOLUTION, Culler, parse_resolution
from ..errors import OccError
from ..loading import load_scene
from .jobs import Progress, load_job, parse_names, prepare_out, require_matplotlib, resolve_cameras, resolve_scene

EXIT_USER_ERROR = 2
CAMERA_HELP = 'camera JSON: one camera or {"frames": [camera, ...]}'
JSON_HELP = "JSON on stdout: per frame the visible names and every object's index, name and state"
ENVELOPE_HELP = ("hide only what stays hidden from every view whose eye is within D scene units of the "
                 "camera's and whose direction is within A degrees of its direction (same lens, any roll)")
QUIET_HELP = "no progress on stderr (a bar on a terminal, else a short line per step); errors still show"


STATE_NAMES = np.array([v.name.lower() for v in sorted(Visibility)])   # "visible", "occluded", "view_culled"


def _frame(scene, state, stats):
    """One frame of the ``--json`` contract: the visible names, every object's state, stats."""
    labels = STATE_NAMES[state].tolist()
    return {"visible": [name for name, s in zip(scene.names, labels, strict=True) if s == "visible"],
            "objects": [{"index": i, "name": name, "state": s}
                        for i, (name, s) in enumerate(zip(scene.names, labels, strict=True))],
            "stats": stats}


def _job(args):
    """Scene and cameras of ``cull`` / ``truth``, every input checked before the GL work."""
    resolution = parse_resolution(args.resolution)
    _display(args, resolution)
    _envelope(args)
    path, sample = resolve_scene(args.scene)
    cameras = resolve_cameras(args.camera, sample)
    return load_scene(path), cameras, resolution


def _display(args, resolution):
    """``--display WxH``: at least the query resolution on both sides, or one error line."""
    if getattr(args, "display", None) is None:
        return None
    display = parse_resolution(args.display)
    if display[0] < resolution[0] or display[1] < resolution[1]:
        raise OccError(f"--display {args.display} must be at least the query resolution "
                       f"{resolution[0]}x{resolution[1]} on both sides")
    return display


def _envelope(args):
    """``--envelope D,A`` as an :class:`core.envelope.Envelope`, or None."""
    if getattr(args, "envelope", None) is None:
        return None
    from ..envelope import Envelope
    return Envelope.parse(args.envelope)


def _frames_progress(args, n):
    """A bar over the frames of ``cull`` / ``truth`` when there are several; elsewhere at most ten lines."""
    return Progress(n, args.command, unit="frame", quiet=args.quiet or n < 2, every=math.ceil(n / 10))


def cmd_cull(args):
    scene, cameras, resolution = _job(args)
    display, envelope = _display(args, resolution), _envelope(args)
    with Culler(scene, resolution, strategy=args.strategy, display=display) as culler, \
            _frames_progress(args, len(cameras)) as progress:
        frames = []
        for i, cam in enumerate(cameras):
            r = culler.cull(cam, envelope=envelope)
            frames.append(_frame(scene, r.state, r.stats.as_dict()))
            progress.step(f"frame {i}: {r.stats.visible} of {len(scene)} visible")
    _print_frames(frames, args.json)


def cmd_truth(args):
    scene, cameras, resolution = _job(args)
    with Culler(scene, resolution, strategy="vfc") as culler, _frames_progress(args, len(cameras)) as progress:
        frames = []
        for i, cam in enumerate(cameras):
            truth = culler.truth(cam)
            # not seen: outside the view volume (by box, as vfc decides) or hidden by others
            state = np.where(truth, Visibility.VISIBLE, np.where(
                culler.cull(cam).state == Visibility.VIEW_CULLED, Visibility.VIEW_CULLED,
                Visibility.OCCLUDED)).astype(np.uint8)
            frames.append(_frame(scene, state, {
                "objects": len(scene), "visible": int(truth.sum()),
                "occluded": int((state == Visibility.OCCLUDED).sum()),
                "view_culled": int((state == Visibility.VIEW_CULLED).sum())}))
            progress.step(f"frame {i}: {int(truth.sum())} of {len(scene)} visible")
    _print_frames(frames, args.json)


def cmd_analyze(args):
    from .analyze import Plan, run_analyze
    resolution = parse_resolution(args.resolution)
    display = _display(args, resolution)
    plan = Plan(args.scene, args.camera, args.frames, resolution, display, args.strategy, args.jobs, args.bake)
    run_analyze(plan, args.out, quiet=args.quiet)


def cmd_merge(args):
    from .analyze import run_merge
    run_merge(args.reports, args.out)


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


def _dump_json(report):
    json.dump(report, sys.stdout, indent=1)
    sys.stdout.write("\n")


def cmd_bench(args):
    if args.hierarchies:
        return cmd_hierarchies(args)
    from .bench import report_json
    from .reports import bench_scene, bench_steps, write_index
    strategies = parse_names(args.strategies, STRATEGIES, "strategies")
    resolution = parse_resolution(args.resolution)
    display, envelope = _display(args, resolution), _envelope(args)
    out = args.out or ((args.plot or args.snapshot) and "reports") or None
    if args.plot or args.snapshot:
        require_matplotlib()
    if out:
        prepare_out(out)
    with Progress(bench_steps(strategies, args.plot, args.snapshot), f"bench {_short_name(args.scene)}",
                  quiet=args.quiet) as progress:
        report, table = bench_scene(args.scene, args.camera, strategies, resolution,
                                    args.frames, out, args.plot, args.snapshot, progress, rounds=args.rounds,
                                    envelope=envelope, display=display)
        if out:
            write_index(out)
    if args.json:
        _dump_json(report_json(report, per_frame=False))
    else:
        print(table)


def cmd_motion(args):
    from .motion import MOTIONS, format_motion, run_motion
    names = parse_names(args.motions, MOTIONS, "motions")
    resolution = parse_resolution(args.resolution)
    if args.latency is not None and not (math.isfinite(args.latency) and 0.0 < args.latency <= 10.0):
        raise OccError(f"--latency must be between 0 and 10 seconds, got {args.latency}")
    if args.update_ms is not None and not (math.isfinite(args.update_ms) and 0.0 <= args.update_ms <= 1e4):
        raise OccError(f"--update-ms must be between 0 and 10000, got {args.update_ms}")
    scene, cameras, title = load_job(args.scene, args.camera, args.frames)
    with Culler(scene, resolution) as culler, \
            Progress(len(names), f"motion {title}", unit="motion", quiet=args.quiet) as progress:
        report = run_motion(culler, cameras, names, args.latency,
                            progress=lambda n, r: progress.step(f"{n}: {r['false_negatives']} FN"),
                            update_ms=args.update_ms)
    if args.json:
        _dump_json({"scene": title, "objects": len(scene), "latency_s": args.latency,
                    "update_ms": args.update_ms, "motions": report})
    else:
        landing = ("passes land when they finish (measured)" if args.latency is None
                   else f"FIXED LATENCY: every pass taken to last {1e3 * args.latency:.0f} ms, not measured")
        if args.update_ms is not None:
            landing += f"; Blender's update after a change taken as {args.update_ms:g} ms"
        print(format_motion(report, f"== {title}: {len(scene)} objects, a look every 1/30 s, {landing} =="))


def cmd_hierarchies(args):
    from .bench import format_hierarchy_table, report_json, run_hierarchies
    from .hierarchy_choice import CANDIDATES
    builders = parse_names(args.hierarchies, CANDIDATES + ("auto",), "hierarchy builders")
    resolution = parse_resolution(args.resolution)
    if args.out:
        prepare_out(args.out)
    scene, cameras, title = load_job(args.scene, args.camera, args.frames)
    with Progress(len(builders), f"hierarchies {title}", unit="builder", quiet=args.quiet) as progress:
        report = run_hierarchies(scene, cameras, builders, resolution, progress=lambda n, s: progress.step(
            f"{n:<9} median {s.frame_ms_median:.2f} ms"))
    report["scene"] = title
    table = format_hierarchy_table(report, f"== {title}: hierarchies ==")
    if args.out:
        with open(os.path.join(args.out, f"{title}_hierarchies.json"), "w") as f:
            json.dump(report_json(report), f, indent=1)
        with open(os.path.join(args.out, f"{title}_hierarchies.txt"), "w") as f:
            f.write(table + "\n")
        from .reports import write_index
        write_index(args.out)
    if args.json:
        _dump_json(report_json(report))
    else:
        print(table)


def cmd_demo(args):
    """The main job: generate the sample scene(s), benchmark them, write the report folder."""
    import sample_scenes

    from .reports import bench_scene, bench_steps, write_index
    resolution = parse_resolution(args.resolution)
    require_matplotlib()
    out = prepare_out(args.out)
    names = sample_scenes.NAMES if args.all else ("city",)
    steps = len(names) * bench_steps(STRATEGIES, plot=True, snapshot=True)
    with Progress(steps, "demo", quiet=args.quiet) as progress:
        for name in names:
            _, table = bench_scene(name, None, STRATEGIES, resolution, args.frames, out, plot=True, snapshot=True,
                                   progress=progress)
            progress.echo(table)
        write_index(out)
    print(f"report written to {out}/ (README.txt says what each file holds)")


def cmd_tradeoff(args):
    from .tradeoff import KNOBS, plot_tradeoff, run_tradeoff, tradeoff_steps
    display = parse_resolution(args.display)
    knobs = parse_names(args.knobs, tuple(KNOBS), "knobs") if args.knobs is not None else list(KNOBS)
    out = args.out or (args.plot and "reports") or None
    if args.plot:
        require_matplotlib()
    if out:
        prepare_out(out)
    scene, cameras, title = load_job(args.scene, args.camera, args.frames)
    with Progress(tradeoff_steps(knobs), f"tradeoff {title}", unit="setting", quiet=args.quiet) as progress:
        # text: a row per setting on stdout stands for its progress line; JSON: rows stay off stdout
        say = progress.note if args.json else progress.echo
        say(f"{title}: {len(scene)} objects, {len(cameras)} frames, display {args.display}")
        report = run_tradeoff(scene, cameras, display, knobs, (lambda *a: None) if args.json else progress.echo,
                              repeats=args.repeats,
                              progress=lambda label, r: progress.step(_tradeoff_step(label, r), line=args.json))
    report["scene"] = title
    if out:
        with open(os.path.join(out, f"{title}_tradeoff.json"), "w") as f:
            json.dump(report, f, indent=1)
        if args.plot:
            plot_tradeoff(report, os.path.join(out, f"{title}_tradeoff.png"), title)
        from .reports import write_index
        write_index(out)
    if args.json:
        _dump_json(report)
    else:
        print(f"Pareto front: {', '.join(report['pareto'])}")


def _tradeoff_step(label, r):
    if r is None:
        return label
    return f"{label} {r['frame_ms_median']:.2f} ms, missed {r['pixels_missed_per_frame']:.1f} px/frame"


def _short_name(spec):
    return os.path.splitext(os.path.basename(spec))[0]


def positive_int(text, hint=""):
    """A count: a whole number >= 1 (0 would silently mean 'all' or 'none')."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got '{text}'") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {value}{hint}")
    return value


def frame_count(text):
    """``--frames``: :func:`positive_int`, whose error says how to get every frame."""
    return positive_int(text, " (leave it out for every frame)")


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line ``error: ...`` and exit status 2, like every other."""

    def error(self, message):
        self.exit(EXIT_USER_ERROR, f"error: {message}; see {self.prog} --help\n")


def build_parser():
    from .jobs import sample_names
    from .tradeoff import KNOBS
    scene_help = (f"scene file (glTF/GLB, OBJ, PLY, ...) or a sample scene: "
                  f"{', '.join(sample_names()) or 'none in this install'} (-small, -joined)")
    p = OneLineParser(prog="python -m core", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    res = f"{DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]}"

    c = sub.add_parser("cull", help="visible objects per camera frame")
    c.add_argument("scene", help=scene_help)
    c.add_argument("--camera", help=CAMERA_HELP)
    c.add_argument("--strategy", default=DEFAULT_STRATEGY, choices=STRATEGIES)
    c.add_argument("--resolution", default=res, help=f"query resolution WxH (default {res})")
    c.add_argument("--display", help="display resolution WxH: queries at --resolution, conservative at this one")
    c.add_argument("--envelope", metavar="D,A", help=ENVELOPE_HELP)
    c.add_argument("--json", action="store_true", help=JSON_HELP)
    c.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    c.set_defaults(func=cmd_cull)

    t = sub.add_parser("truth", help="exact visible set from an object-ID buffer")
    t.add_argument("scene", help=scene_help)
    t.add_argument("--camera", help=CAMERA_HELP)
    t.add_argument("--resolution", default=res, help=f"ID-buffer resolution WxH (default {res})")
    t.add_argument("--json", action="store_true", help=JSON_HELP)
    t.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    t.set_defaults(func=cmd_truth)

    a = sub.add_parser("analyze", help="which objects a camera path sees, per frame and per object: "
                       "the report occ.analyze writes (JSON and CSV)")
    a.add_argument("scene", help=scene_help)
    a.add_argument("--camera", help="camera path JSON (default: the sample scene's own path)")
    a.add_argument("--frames", metavar="A:B", help="only the path's frames A to B, 0-based, B excluded "
                   "(A: to the end, :B from the start; default all): a chunk that merge joins")
    # a strategy whose answer depends on timing (auto) would not give a repeatable report
    a.add_argument("--strategy", default=DEFAULT_STRATEGY, choices=[s for s in STRATEGIES if not REGISTRY[s].timed],
                   help=f"(default {DEFAULT_STRATEGY}; not auto, whose answer depends on timing)")
    a.add_argument("--resolution", default=res, help=f"query resolution WxH (default {res})")
    a.add_argument("--display", help="display resolution WxH: queries at --resolution, conservative at this one")
    a.add_argument("--out", metavar="DIR", help=f"write DIR/{ANALYSIS_REPORT} and DIR/report.csv "
                   "(default: the JSON on stdout)")
    a.add_argument("--bake", action="store_true",
                   help="each frame's set holds for the camera's whole motion until the next path frame "
                        "(an envelope pass a frame; a lens change between two frames keeps every object): "
                        "what a baked shot may hide per frame")
    a.add_argument("--jobs", type=positive_int, default=1,
                   help="split the frames into N contiguous chunks, one process each, merged at the end")
    a.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    a.set_defaults(func=cmd_analyze)

    g = sub.add_parser("merge", help="join the chunk reports of one analysis into the whole run's report")
    g.add_argument("reports", nargs="+", metavar="DIR",
                   help=f"a report folder (its {ANALYSIS_REPORT}; without one, every .json in it) or a report JSON")
    g.add_argument("--out", metavar="DIR", help=f"write DIR/{ANALYSIS_REPORT} and DIR/report.csv "
                   "(default: the JSON on stdout)")
    g.set_defaults(func=cmd_merge)

    b = sub.add_parser("bench", help="every strategy over a camera path, against the truth")
    b.add_argument("scene", help=scene_help)
    b.add_argument("--camera", help="camera path JSON (default: the sample scene's own path)")
    b.add_argument("--strategies", default=",".join(STRATEGIES), help="comma list (default: all)")
    b.add_argument("--resolution", default=res, help=f"query resolution WxH (default {res})")
    b.add_argument("--frames", type=frame_count, help="use only this many frames, evenly spread")
    b.add_argument("--rounds", type=positive_int, default=1,
                   help="the path this many times per strategy, the order rotated each round; the median "
                        "frame is the median of the rounds' (ratios that hold on a busy machine)")
    b.add_argument("--display", help="display resolution WxH: queries at --resolution, conservative at this "
                   "one; false negatives counted against the truth at this one")
    b.add_argument("--envelope", metavar="D,A", help="also a row 'envelope D,A': " + ENVELOPE_HELP +
                   ", as live mode asks it (the eyes kept off the nearest face where the pass "
                   "finds one); its FN counts views of the envelope each pass used too (a few per frame)")
    b.add_argument("--out", help="report folder (default reports/ with --plot or --snapshot)")
    b.add_argument("--plot", action="store_true", help="PNG plots along the path")
    b.add_argument("--snapshot", action="store_true", help="pictures of one frame")
    b.add_argument("--hierarchies", help="compare hierarchy builders instead of strategies: "
                   "comma list of tree, pHBVO, DBVS, octree, balanced, auto")
    b.add_argument("--json", action="store_true", help="the report as JSON on stdout (progress on stderr)")
    b.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    b.set_defaults(func=cmd_bench)

    m = sub.add_parser("motion", help="replay motions under live mode's policy: visible-but-hidden objects")
    m.add_argument("scene", help=scene_help)
    m.add_argument("--camera", help="camera path JSON (default: the sample scene's own path)")
    m.add_argument("--motions", default="drag,orbit,dolly,walk", help="comma list of drag, orbit, dolly, walk")
    m.add_argument("--resolution", default=res, help=f"query resolution WxH (default {res})")
    m.add_argument("--frames", type=frame_count, help="use only this many frames of the path, evenly spread")
    m.add_argument("--latency", type=float, default=None,
                   help="take every pass to last this many seconds instead of its measured time (a fixed "
                        "latency: counts that do not depend on this machine's speed, but not what a user gets)")
    m.add_argument("--update-ms", type=float, default=None,
                   help="Blender's update after each change of the hidden set, in ms (live mode measures it; "
                        "default: not modelled): a set during motion is shown only where it pays for it")
    m.add_argument("--json", action="store_true", help="the report as JSON on stdout")
    m.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    m.set_defaults(func=cmd_motion)

    d = sub.add_parser("demo", help="generate the sample scene(s) and benchmark them")
    d.add_argument("--all", action="store_true", help="every sample scene, not only city")
    d.add_argument("--out", default="reports", help="report folder (default reports/)")
    d.add_argument("--resolution", default=res, help=f"query resolution WxH (default {res})")
    d.add_argument("--frames", type=frame_count, help="use only this many frames, evenly spread")
    d.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    d.set_defaults(func=cmd_demo)

    o = sub.add_parser("tradeoff", help="sweep the speed/accuracy knobs against display truth")
    o.add_argument("scene", help=scene_help)
    o.add_argument("--camera", help=CAMERA_HELP + " (default: a sample scene's own path)")
    o.add_argument("--display", default="1920x1080", help="display resolution for the truth")
    o.add_argument("--frames", type=positive_int, default=24, help="frames of the path, evenly spread")
    o.add_argument("--repeats", type=positive_int, default=3,
                   help="runs of the path per setting; times are medians with their spread (default 3)")
    o.add_argument("--knobs", help=f"comma list of {', '.join(KNOBS)} (default all)")
    o.add_argument("--out", help="folder for the JSON and the Pareto plot (default reports/ with --plot)")
    o.add_argument("--plot", action="store_true", help="the speed/accuracy plot (PNG)")
    o.add_argument("--json", action="store_true", help="the report as JSON on stdout (progress on stderr)")
    o.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    o.set_defaults(func=cmd_tradeoff)
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except OccError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USER_ERROR
    except BrokenPipeError:          # the reader (e.g. `| head`) stopped reading: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    return 0
