"""Occlusion-culling engine: numpy on the CPU, moderngl/EGL (in ``core.gl``) on the GPU.

Never imports bpy.  The GPU backend is imported lazily by :class:`Culler`, so the
numeric modules work (and are tested) without a GL context.
"""

from .camera import Camera, load_cameras
from .cull import (
    DEFAULT_STRATEGY,
    REGISTRY,
    STAT_KEYS,
    STRATEGIES,
    CullResult,
    PassStats,
    Visibility,
    make_strategy,
    repeatable,
)
from .engine import Culler
from .errors import OccError
from .loading import load_scene
from .scene import Scene

__all__ = ["Camera", "Culler", "CullResult", "PassStats", "OccError", "Scene", "Visibility", "load_cameras",
           "load_scene", "REGISTRY", "STAT_KEYS", "STRATEGIES", "DEFAULT_STRATEGY", "make_strategy",
           "repeatable"]
