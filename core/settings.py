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

MAX_RESOLUTION = 8192          # per side; beyond this llvmpipe and most GPUs refuse targets


def check_resolution(resolution, display=None):
    """``((w, h), (dw, dh))``: a pass's query resolution and its display resolution (the
    query's where ``display`` is None), each 1 to :data:`MAX_RESOLUTION` per side, the
    display at least the query; an :class:`OccError` naming the sizes otherwise.  The one
    rule the engine, its renderers and the add-on's setting share."""
    w, h = (int(x) for x in resolution)
    dw, dh = (w, h) if display is None else (int(x) for x in display)
    for what, (a, b) in (("resolution", (w, h)), ("display resolution", (dw, dh))):
        if not (1 <= a <= MAX_RESOLUTION and 1 <= b <= MAX_RESOLUTION):
            raise OccError(f"{what} must be between 1x1 and {MAX_RESOLUTION}x{MAX_RESOLUTION}, got {a}x{b}")
    if dw < w or dh < h:
        raise OccError(f"display resolution {dw}x{dh} must be at least the query resolution {w}x{h}")
    return (w, h), (dw, dh)


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
