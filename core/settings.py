"""The knobs of a culling pass and the two presets users choose between.

``conservative`` (default) queries at the display resolution: nothing the display
shows is culled -- a depth buffer at a lower resolution can close a gap of one
display pixel, so it is not used by default.  ``fast`` queries at half the display
resolution per side (a quarter of the pixels) and grows query boxes by one query
pixel, so tiny objects between low-resolution pixel centres are kept; its error
is measured by ``python -m core tradeoff`` and written in docs/performance.md.
"""

from dataclasses import dataclass, replace

from .errors import OccError
from .occupancy import DEFAULT_TILES


@dataclass(frozen=True)
class CullOptions:
    """tiles: occupancy-map tiles; visible_threshold: samples a query must pass
    beyond which the box is visible (0 = any sample: exact at the query
    resolution); pixel_guard: query boxes grow by this many query pixels (at
    their farthest point); chunk: nodes per front-to-back step of the
    occupancy-map stage; resolution_scale: query resolution over display
    resolution."""

    tiles: int = DEFAULT_TILES
    visible_threshold: int = 0
    pixel_guard: float = 0.0
    chunk: int = 16
    resolution_scale: float = 1.0

    def __post_init__(self):
        if self.tiles < 1 or self.chunk < 1 or self.visible_threshold < 0 or self.pixel_guard < 0:
            raise OccError(f"invalid culling options {self}")
        if not 0.0 < self.resolution_scale <= 1.0:
            raise OccError(f"resolution_scale must be in (0, 1], got {self.resolution_scale}")

    def with_(self, **changes):
        return replace(self, **changes)


PRESETS = {
    "conservative": CullOptions(),
    "fast": CullOptions(resolution_scale=0.5, pixel_guard=1.0),
}
DEFAULT_PRESET = "conservative"


def preset(name):
    if name not in PRESETS:
        raise OccError(f"unknown preset '{name}'; choose one of {', '.join(PRESETS)}")
    return PRESETS[name]


def query_resolution(display, options):
    """Query resolution for a display ``(W, H)`` under ``options`` (at least 1x1)."""
    w, h = display
    s = options.resolution_scale
    return max(1, round(w * s)), max(1, round(h * s))
