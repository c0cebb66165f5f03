"""The GPU backend: the only part of the engine that imports moderngl.

``OCC_GL=4.1`` forces the OpenGL 4.1 core path (what macOS has); see :mod:`.context`.
:mod:`.renderer` is the renderer interface and what both paths share,
:mod:`.renderer_43` and :mod:`.renderer_41` the paths; :mod:`.gpucull` is the ``gpu``
strategy's GPU-resident pass (4.3 path only), :mod:`.layout` its contract with its
shaders (``core/gl/glsl/``, loaded by :mod:`.shaders`).
"""

from .context import create_context
from .renderer import GLRenderer, PendingQuery, Renderer

__all__ = ["GLRenderer", "PendingQuery", "Renderer", "create_context"]
