"""The GPU backend: the only part of the engine that imports moderngl.

``OCC_GL=4.1`` forces the OpenGL 4.1 core path (what macOS has); see :mod:`.context`.
:mod:`.gpucull` is the ``gpu`` strategy's GPU-resident pass (4.3 path only).
"""

from .context import create_context
from .renderer import GLRenderer, PendingQuery

__all__ = ["GLRenderer", "PendingQuery", "create_context"]
