"""What a command works on: a scene (file or sample name), its cameras, a title.

Shared by the command line (:mod:`core.lab.cli`), the benchmark and the hierarchy
choice, so that none of them imports another's front-end.  Everything here
checks its input before any long work starts and raises :class:`OccError`.
"""

import os
import sys
import tempfile

from ..camera import cameras_from_json, load_cameras
from ..errors import OccError
from ..loading import load_scene


def sample_names():
    """Names of the bundled sample scenes (empty outside a repository checkout)."""
    try:
        import sample_scenes
        return tuple(sample_scenes.NAMES)
    except (ImportError, AttributeError):
        return ()


def parse_sample(spec):
    """``"city-small-joined"`` -> ``("city", small, joined)``, or None for no sample name."""
    base, small, joined = spec, False, False
    if base.endswith("-joined"):
        base, joined = base[:-7], True
    if base.endswith("-small"):
        base, small = base[:-6], True
    return (base, small, joined) if base in sample_names() else None


def resolve_scene(spec):
    """A scene file path, or the name of a bundled sample scene -> (path, sample spec or None).

    The sample spec is ``(name, small, joined)``.
    """
    if os.path.isdir(spec):
        raise OccError(f"{spec} is a directory; SCENE must be a scene file (glTF/GLB, OBJ, PLY, ...) "
                       "or a sample scene name")
    if os.path.exists(spec):
        return spec, None
    sample = parse_sample(spec)
    if sample is not None:
        import sample_scenes
        name, small, joined = sample
        return str(sample_scenes.scene_path(name, small=small, joined=joined)), sample
    names = sample_names()
    hint = (f" (or a sample scene: {', '.join(names)}; -small for the small variant, -joined for "
            "all objects merged into one mesh)" if names else "")
    raise OccError(f"scene file not found: {spec}{hint}")


def resolve_cameras(camera_arg, sample):
    """Cameras from ``--camera``, or the sample scene's own path (fitted to its size)."""
    if camera_arg:
        return load_cameras(camera_arg)
    if sample is None:
        raise OccError("--camera CAM.json is required for a scene file")
    import sample_scenes
    name, small, _ = sample
    return cameras_from_json(sample_scenes.default_camera_path(name, small=small))


def spread(items, k):
    """At most ``k`` items, evenly spread over the list (all of them when k is None)."""
    if k is None:
        return items
    return items[:: max(1, len(items) // k)][:k]


def load_job(scene_spec, camera_arg, frames=None):
    """Scene, cameras (at most ``frames`` of them, evenly spread) and a title for reports."""
    path, sample = resolve_scene(scene_spec)
    cameras = spread(resolve_cameras(camera_arg, sample), frames)
    title = scene_spec if sample else os.path.splitext(os.path.basename(path))[0]
    return load_scene(path), cameras, title


class Progress:
    """Progress of one long command, always on stderr (stdout carries the result, or pure JSON).

    On a terminal: a bar, tqdm's when it is installed, else a plain one redrawn in place.
    Elsewhere (CI, pipes, files): one short line per step that has a text, and at most every
    ``every``-th step.  With ``quiet``: nothing.  tqdm is imported here and only for a bar: the
    Blender extension does not bundle it, and nothing in ``core`` needs it to import.
    """

    def __init__(self, total, desc, unit="step", quiet=False, every=1, stream=None):
        self.total, self.desc, self.unit, self.every = int(total), desc, unit, max(1, int(every))
        self.stream = stream or sys.stderr
        self.n, self.label, self._tqdm = 0, "", None
        self.mode = "quiet" if quiet else ("bar" if _isatty(self.stream) else "lines")
        if self.mode == "bar":
            try:
                from tqdm import tqdm
            except ImportError:              # the plain bar below: a missing tqdm costs only looks
                tqdm = None
            if tqdm is not None:
                self._tqdm = tqdm(total=self.total, desc=desc, unit=unit, file=self.stream,
                                  dynamic_ncols=True, leave=False)
            else:
                self._draw()

    def step(self, text=None, line=True):
        """One step done; ``text`` names it (bar: shown beside it; elsewhere: its line, unless
        ``line`` is False because the caller prints its own line for it)."""
        self.n += 1
        self.label = text or ""
        if self.mode == "bar":
            if self._tqdm is not None:
                self._tqdm.set_postfix_str(_short(self.label), refresh=False)
                self._tqdm.update(1)
            else:
                self._draw()
        elif self.mode == "lines" and text and line and (self.n % self.every == 0 or self.n == self.total):
            print(f"  [{self.n}/{self.total}] {text}", file=self.stream, flush=True)

    def note(self, text):
        """A line of information on stderr, above the bar on a terminal; nothing when quiet."""
        if self.mode != "quiet":
            self._write(text, self.stream)

    def echo(self, text):
        """A line of the result on stdout, even when quiet; on a terminal it does not tear the bar."""
        self._write(text, sys.stdout)

    def close(self):
        if self._tqdm is not None:
            self._tqdm.close()
            self._tqdm = None
        elif self.mode == "bar":
            self._clear()
            self.mode = "closed"

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _write(self, text, stream):
        if self._tqdm is not None:
            self._tqdm.write(text, file=stream)
            return
        if self.mode == "bar":
            self._clear()
        print(text, file=stream, flush=True)
        if self.mode == "bar":
            self._draw()

    def _width(self):
        try:                                 # the terminal of stderr, not of stdout (maybe a pipe)
            columns = os.get_terminal_size(self.stream.fileno()).columns
        except (AttributeError, ValueError, OSError):
            columns = 80
        return max(20, (columns or 80) - 1)

    def _draw(self):
        done = int(20 * self.n / max(self.total, 1))
        text = f"{self.desc} [{'#' * done}{'-' * (20 - done)}] {self.n}/{self.total} {self.unit}s {self.label}"
        self.stream.write("\r" + text[:self._width()].ljust(self._width()))
        self.stream.flush()

    def _clear(self):
        self.stream.write("\r" + " " * self._width() + "\r")
        self.stream.flush()


def _isatty(stream):
    try:
        return stream.isatty()
    except (AttributeError, ValueError):     # a closed or file-like stream: no terminal
        return False


def _short(text, width=32):
    return text if len(text) <= width else text[:width - 1] + "~"


def parse_names(text, allowed, what):
    """``"a,b"`` -> ``["a", "b"]``, each one of ``allowed``; an empty list is an error."""
    names = [s.strip() for s in str(text).split(",") if s.strip()]
    if not names:
        raise OccError(f"no {what} given in '{text}'; choose from {', '.join(allowed)}")
    unknown = [s for s in names if s not in allowed]
    if unknown:
        raise OccError(f"unknown {what} {', '.join(unknown)}; choose from {', '.join(allowed)}")
    return names


def prepare_out(path):
    """Create the report folder ``path`` now, so that a bad one fails before the work, not after."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise OccError(f"--out {path} is a file; give a folder for the report")
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as e:
        raise OccError(f"cannot create the report folder {path}: {e.strerror}") from None
    try:                                     # the real test (root ignores permission bits)
        tempfile.TemporaryFile(dir=path).close()
    except OSError as e:
        raise OccError(f"cannot write to the report folder {path}: {e.strerror}") from None
    return path


def require_matplotlib():
    """Plots need matplotlib: say so before the work, not after it."""
    import importlib.util
    if importlib.util.find_spec("matplotlib") is None:
        raise OccError("--plot needs matplotlib: pip install matplotlib")
