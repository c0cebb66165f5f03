"""The GPU backend: the only part of the engine that imports moderngl."""

from .renderer import GLRenderer, create_context

__all__ = ["GLRenderer", "create_context"]
