"""The GPU backend: the only part of the engine that imports moderngl.

``OCC_GL=4.1`` forces the OpenGL 4.1 core path (what macOS has); see :mod:`.context`.
:mod:`.renderer` is the renderer interface and what both paths share,
:mod:`.renderer_43` and :mod:`.renderer_41` the paths; :mod:`.gpucull` is the ``gpu``
strategy's GPU-resident pass (4.3 path only), :mod:`.layout` its contract with its
shaders (``core/gl/glsl/``, loaded by :mod:`.shaders`).
"""

from ..settings import check_resolution
from .context import choose_path, create_context
from .renderer import BaseRenderer, PendingQuery, Renderer, release_context
from .renderer_41 import Renderer41
from .renderer_43 import Renderer43


def GLRenderer(scene, width: int, height: int, ctx=None, units=None, display=None,  # noqa: N802
               path: str | None = None) -> "BaseRenderer":
    """The renderer of ``scene`` on ``ctx`` (a new context when None, released with the
    renderer) for GL ``path`` (default ``OCC_GL``, else the best the context has): a
    :class:`~core.gl.renderer_43.Renderer43` or :class:`~core.gl.renderer_41.Renderer41`.
    A factory named as the class it was, so call sites construct it as before."""
    check_resolution((width, height), display)    # before a context is made
    own = ctx is None
    ctx = create_context() if own else ctx
    cls = {"4.3": Renderer43, "4.1": Renderer41}[choose_path(ctx, path)]
    r = cls(scene, width, height, ctx=ctx, units=units, display=display)
    r.own_ctx = own
    return r


__all__ = ["GLRenderer", "PendingQuery", "Renderer", "create_context", "release_context"]
