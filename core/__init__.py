"""Occlusion-culling engine: numpy on the CPU, moderngl/EGL (in ``core.gl``) on the GPU.

Never imports bpy.  The GPU backend is imported lazily by :class:`Culler`, so the
numeric modules work (and are tested) without a GL context.
"""

from .camera import Camera, load_cameras
from .engine import Culler, CullResult
from .errors import OccError
from .scene import Scene, load_scene
from .strategies import DEFAULT_STRATEGY, STRATEGIES
from .traversal import Visibility

__all__ = ["Camera", "Culler", "CullResult", "OccError", "Scene", "Visibility", "load_cameras",
           "load_scene", "STRATEGIES", "DEFAULT_STRATEGY"]
