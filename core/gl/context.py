"""OpenGL contexts and the choice between the two GL paths.

Two paths, same answers:

- ``"4.3"`` (Linux, Windows): one ``glMultiDrawElementsIndirect`` per draw, and every
  box of a query batch in ONE instanced draw whose fragments count samples into a
  shader storage buffer, read back once per batch.
- ``"4.1"`` (macOS stops at OpenGL 4.1 core): one draw per unit with a uniform MVP,
  one classic occlusion query object per box; no storage buffers, no multi-draw
  indirect, no baseInstance.

The environment variable ``OCC_GL`` picks the path: ``OCC_GL=4.1`` forces the 4.1 path
(on any machine: the test suite runs the engine a second time this way),
``OCC_GL=4.3`` requires 4.3 (an error where it is missing).  Unset: 4.3 where the
context has it, else 4.1.  ``OCC_LIBEGL`` names a specific libEGL on Linux.
"""

import os
import sys

from ..errors import OccError

PATHS = {"4.3": 430, "4.1": 410}       # path name -> the GL version it needs
EGL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"


def requested_path():
    """The path the ``OCC_GL`` environment variable asks for, or None (automatic)."""
    want = os.environ.get("OCC_GL", "").strip()
    if not want:
        return None
    if want not in PATHS:
        raise OccError(f"OCC_GL must be one of {', '.join(PATHS)} (or unset), got {want!r}")
    return want


def platform_hint():
    """What a user of this platform can do when no context can be made."""
    if sys.platform.startswith("linux"):
        return f"install Mesa's EGL (Debian/Ubuntu: apt-get install {EGL_PACKAGES})"
    if sys.platform == "darwin":
        return "the engine needs OpenGL 4.1 core, which every Mac since 2012 has; check the error above"
    return "update the GPU driver (OpenGL 4.3, or at least 4.1, is required)"


def create_context():
    """A standalone OpenGL context: 4.3 where the driver has it, else 4.1 core.

    EGL on Linux (headless, no display).  ``OCC_GL`` narrows the choice (module doc).
    """
    try:
        import moderngl
    except ImportError:
        raise OccError("the GPU backend needs moderngl: pip install moderngl") from None
    kwargs = {"backend": "egl"} if sys.platform.startswith("linux") else {}
    if os.environ.get("OCC_LIBEGL"):          # a specific libEGL (or, in tests, a missing one)
        kwargs["libegl"] = os.environ["OCC_LIBEGL"]
    want = requested_path()
    tries = [want] if want else ["4.3", "4.1"]
    failures = []
    for path in tries:
        try:
            return moderngl.create_context(standalone=True, require=PATHS[path], **kwargs)
        except Exception as e:  # moderngl/glcontext raise plain Exceptions for missing libraries
            failures.append(f"OpenGL {path}: {e}")
    raise OccError(f"no OpenGL context could be created ({'; '.join(failures)}); {platform_hint()}")


def choose_path(ctx, path=None):
    """The path a renderer on ``ctx`` takes: ``path``, else ``OCC_GL``, else the best the context has."""
    path = path or requested_path()
    if path is None:
        return "4.3" if ctx.version_code >= PATHS["4.3"] else "4.1"
    if path not in PATHS:
        raise OccError(f"GL path must be one of {', '.join(PATHS)}, got {path!r}")
    if ctx.version_code < PATHS[path]:
        raise OccError(f"the OpenGL {path} path needs a {path} context, this one is "
                       f"{ctx.version_code // 100}.{ctx.version_code % 100 // 10}; {platform_hint()}")
    return path
