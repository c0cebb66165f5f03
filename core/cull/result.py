"""What a pass answers: three states per object (as in Masked Occlusion Culling) and
the pass's counters, read by the engine's callers (the add-on, the benchmark, reports,
the CLI).

VISIBLE, OCCLUDED (a query proved it hidden) and VIEW_CULLED (outside the frustum).
"""

from dataclasses import dataclass, fields
from enum import IntEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray


class Visibility(IntEnum):
    VISIBLE = 0
    OCCLUDED = 1
    VIEW_CULLED = 2


@dataclass
class PassStats:
    """The counters of one pass: its work, its time, and its answer.

    Every pass fills the first two groups (strategies add to them, :class:`CullPass`
    times them); the engine fills the answer; an envelope pass (:mod:`core.envelope`)
    also says its envelope and, under lights, its shadow boxes.  :meth:`as_dict` is the
    JSON form the CLI, the benchmark and the reports write: the same keys, in this
    order, the envelope's and the shadows' only when set.
    """

    # work
    queries: int = 0                 # boxes tested
    queries_skipped: int = 0         # boxes drawn or opened without a test (the map, the memory)
    near_visible: int = 0            # boxes at the near plane: visible without a test
    multiple_queries: int = 0        # test batches (one draw, one read-back each)
    samples_passed: int = 0
    query_rect_pixels: int = 0       # pixels of the tested boxes' screen rectangles
    triangles_drawn: int = 0
    units_drawn: int = 0
    nodes_visited: int = 0
    query_raster_pixels: int = 0     # pixels the tested boxes rasterise
    triangles_occluded: int = 0      # triangles proved hidden and never drawn
    occlusion_pass: int = 0          # auto: 1 when the pass tested occlusion
    fresh: int = 0                   # 1 when the pass started without memory
    invalid_objects: int = 0         # objects with NaN or infinite values (kept visible)
    clipped_objects: int = 0         # objects a clipping region cuts (kept visible, no occluders)
    gl_calls: int = 0                # -1: a renderer that does not count them
    blocking_reads: int = 0
    # time, ms
    frustum_ms: float = 0.0
    traversal_ms: float = 0.0
    query_ms: float = 0.0
    draw_ms: float = 0.0
    gl_ms: float = 0.0
    cpu_ms: float = 0.0              # the pass outside GL calls (what a faster GPU cannot shorten)
    total_ms: float = 0.0
    # envelope passes under lights
    shadow_boxes: int | None = None
    shadow_casters_kept: int | None = None
    # envelope passes
    envelope_distance: float | None = None
    envelope_angle_deg: float | None = None
    envelope_any_roll: bool | None = None
    envelope_occluders: int | None = None     # objects drawn into the envelope's image
    envelope_image_hidden: int | None = None  # boxes its image proved hidden (None: not drawn)
    # the answer
    objects: int = 0
    visible: int = 0
    occluded: int = 0
    view_culled: int = 0
    triangles_total: int = 0
    triangles_visible: int = 0

    def as_dict(self) -> dict:
        """The counters as plain JSON values, unset ones left out."""
        return {f.name: v for f in fields(self) if (v := getattr(self, f.name)) is not None}


# The counters every pass has (the work and the time), in their JSON order.
STAT_KEYS = tuple(f.name for f in fields(PassStats))[:tuple(f.name for f in fields(PassStats)).index("shadow_boxes")]


@dataclass
class CullResult:
    """Three states per object, the counters of the pass and its occupancy map;
    ``envelope``: the :class:`core.envelope.Envelope` its hidden set holds for (None: a
    point pass, which holds for its own view only)."""

    state: NDArray[np.uint8]
    stats: PassStats
    occupancy: NDArray[np.bool_]
    envelope: Any = None

    @property
    def visible(self) -> NDArray[np.bool_]:
        """``(n,) bool``: objects not culled."""
        return self.state == Visibility.VISIBLE
