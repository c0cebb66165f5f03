"""``python -m core analyze`` and ``merge``: which objects a camera path ever sees, in one
process, in chunks over several (``--jobs``) or on a farm, and chunk reports joined.

The report is :mod:`core.analysis`'s, the one ``occ.analyze`` writes.  Every frame is
culled as a new engine's first pass (``cull(camera, fresh=True)``): a frame's answer
never depends on the frames before it, so chunks merge into exactly the whole run's
report.  Every input is checked before any work; nothing is written until the report
is complete, and then under a temporary name renamed into place.
"""

import json
import os
import re
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np

from ..analysis import REPORT_NAME, build_report, merge_reports, read_report, report_files, source_block, write_report
from ..camera import Camera
from ..cull import Visibility
from ..errors import OccError
from .jobs import Progress, resolve_cameras, resolve_scene

RULE = "seen"             # the engine's answer: a pixel of the object is seen (no lights headless)
FRAMES = re.compile(r"^\s*(\d*)\s*:\s*(\d*)\s*$")


def parse_frames(text: str | None, n: int) -> tuple[int, int]:
    """``--frames A:B`` -> ``(A, B)``: path indices, 0-based, B excluded; ``A:`` runs to
    the end, ``:B`` from the start; None: the whole path of ``n`` frames."""
    if text is None:
        return 0, n
    m = FRAMES.match(str(text))
    if not m:
        raise OccError(f"--frames must look like A:B (0-based path indices, B excluded, e.g. 0:{n}), got '{text}'")
    a = int(m.group(1)) if m.group(1) else 0
    b = int(m.group(2)) if m.group(2) else n
    if b <= a:
        raise OccError(f"--frames {text} holds no frame: B must be greater than A (B is excluded)")
    if b > n:
        raise OccError(f"--frames {text} runs past the camera path's end: it has {n} frames (0:{n})")
    return a, b


def check_out(path: str | None) -> None:
    """An ``--out`` folder that can be written, checked without creating anything."""
    if path is None:
        return
    if os.path.exists(path) and not os.path.isdir(path):
        raise OccError(f"--out {path} is a file; give a folder for the report")
    probe = os.path.abspath(path)
    while not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if not os.path.isdir(probe):
        raise OccError(f"--out {path}: {probe} is a file, not a folder")
    try:                                     # the real test (root ignores permission bits)
        tempfile.TemporaryFile(dir=probe).close()
    except OSError as e:
        raise OccError(f"cannot write the report folder {path} (in {probe}): {e.strerror}") from None


def cameras_sha1(cameras: list[Camera]) -> str:
    """A digest of a camera path (every view and projection, float64)."""
    import hashlib
    data = np.stack([np.stack([c.view, c.projection]) for c in cameras]).astype("<f8")
    return hashlib.sha1(data.tobytes()).hexdigest()


class Plan:
    """An analysis checked and ready: the scene file, its title, the whole camera path,
    the frames ``[a, b)``, the engine's settings and the chunks of ``--jobs``."""

    def __init__(self, scene_spec, camera, frames, resolution, display, strategy, jobs=1, bake=False):
        path, sample = resolve_scene(scene_spec)
        self.path = path
        self.title = scene_spec if sample else os.path.basename(path)
        self.cameras = resolve_cameras(camera, sample)
        self.a, self.b = parse_frames(frames, len(self.cameras))
        self.resolution, self.display, self.strategy = tuple(resolution), display, strategy
        self.bake = bool(bake)
        pieces = np.array_split(np.arange(self.a, self.b), min(int(jobs), self.b - self.a))
        self.chunks = [(int(p[0]), int(p[-1]) + 1) for p in pieces]

    def settings(self) -> dict:
        return {"strategy": self.strategy, "resolution": list(self.resolution),
                "display": list(self.display) if self.display else None, "rule": RULE, "frame_step": 1,
                "within_frame": self.bake}


def frame_envelope(cameras: list[Camera], i: int):
    """The envelope a baked frame ``i`` of the path ``cameras`` holds for: every view the
    camera passes through until the next frame, taken as moving straight from one eye to
    the next and turning along the shortest rotation between the two frames
    (:func:`core.envelope.covering` of the next frame's view).  None: the path's last
    frame (its own view only); ``False``: no envelope holds (the lens changes, or the
    camera turns too far): the frame hides nothing."""
    from ..envelope import covering
    if i + 1 >= len(cameras):
        return None
    return covering(cameras[i], [cameras[i + 1]])


def analyze_chunk(plan: Plan, a: int, b: int, progress=None) -> dict:
    """The report of frames ``[a, b)`` of ``plan``'s path, each culled as a new engine's
    first pass."""
    from ..engine import Culler
    from ..loading import load_scene
    scene = load_scene(plan.path)
    names = list(scene.names)
    per_frame = []
    with Culler(scene, plan.resolution, strategy=plan.strategy, display=plan.display) as culler:
        for i in range(a, b):
            envelope = frame_envelope(plan.cameras, i) if plan.bake else None
            if envelope is False:                 # no envelope holds: every object stays
                state = np.full(len(names), Visibility.VISIBLE, dtype=np.uint8)
            else:
                state = culler.cull(plan.cameras[i], fresh=True, envelope=envelope).state
            visible = [names[k] for k in np.flatnonzero(state == Visibility.VISIBLE)]
            per_frame.append({"frame": i, "visible": visible})
            if progress is not None:
                progress.step(f"frame {i}: {len(visible)} of {len(names)} visible")
    source = source_block(plan.title, names, plan.settings(),
                          cameras={"count": len(plan.cameras), "sha1": cameras_sha1(plan.cameras)})
    return build_report(per_frame, names, RULE, source)


def _chunk_process(plan: Plan, a: int, b: int, path: str) -> str:
    """In a spawned process (its own GL context): frames ``[a, b)`` into the report ``path``."""
    write_report(analyze_chunk(plan, a, b), path)
    return path


def run_analyze(plan: Plan, out: str | None, quiet: bool = False) -> dict:
    """The analysis of ``plan``: in this process, or its chunks in one spawned process
    each, their reports merged here.  Written to ``out/report.json`` (and ``.csv``)."""
    check_out(out)
    n = plan.b - plan.a
    if len(plan.chunks) == 1:
        with Progress(n, "analyze", unit="frame", quiet=quiet or n < 2, every=max(1, n // 10)) as progress:
            report = analyze_chunk(plan, plan.a, plan.b, progress)
    else:
        with tempfile.TemporaryDirectory(prefix="occ-chunks-") as tmp, \
                Progress(len(plan.chunks), "analyze", unit="chunk", quiet=quiet) as progress, \
                ProcessPoolExecutor(len(plan.chunks), mp_context=get_context("spawn")) as pool:
            futures = [pool.submit(_chunk_process, plan, a, b, os.path.join(tmp, f"chunk_{a}_{b}.json"))
                       for a, b in plan.chunks]
            paths = []
            for (a, b), fut in zip(plan.chunks, futures, strict=True):
                paths.append(fut.result())
                progress.step(f"frames {a}:{b}")
            report = merge_reports([read_report(p) for p in paths], paths)
    _emit(report, out)
    return report


def run_merge(specs: list[str], out: str | None) -> dict:
    """The chunk reports ``specs`` name (files, or folders: see
    :func:`core.analysis.report_files`) merged into one, written to ``out``."""
    check_out(out)
    paths = [p for spec in specs for p in report_files(spec)]
    report = merge_reports([read_report(p) for p in paths], paths)
    _emit(report, out)
    return report


def _emit(report: dict, out: str | None) -> None:
    if out is None:
        json.dump(report, sys.stdout, indent=1)
        sys.stdout.write("\n")
        return
    try:
        write_report(report, os.path.join(out, REPORT_NAME))
    except OSError as e:
        raise OccError(f"cannot write the report into {out}: {e.strerror or e}") from None
    print(f"report written to {os.path.join(out, REPORT_NAME)} (and report.csv): {report['frame_count']} frames, "
          f"{sum(o['frames_visible'] == 0 for o in report['objects'].values())} of {len(report['objects'])} "
          "objects never visible")
