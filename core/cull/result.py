"""What a pass answers: three states per object (as in Masked Occlusion Culling) and
the pass's counters, read by the engine's callers (the add-on, the benchmark, reports,
the CLI).

VISIBLE, OCCLUDED (a query proved it hidden) and VIEW_CULLED (outside the frustum).
"""

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


class Visibility(IntEnum):
    VISIBLE = 0
    OCCLUDED = 1
    VIEW_CULLED = 2


STAT_KEYS = ("queries", "queries_skipped", "near_visible", "multiple_queries", "samples_passed",
             "query_rect_pixels", "triangles_drawn", "units_drawn", "nodes_visited",
             "query_raster_pixels", "triangles_occluded", "occlusion_pass", "fresh", "invalid_objects",
             "gl_calls", "blocking_reads",
             "frustum_ms", "traversal_ms", "query_ms", "draw_ms", "gl_ms", "cpu_ms", "total_ms")



@dataclass
class CullResult:
    """Three states per object, the counters of the pass and its occupancy map."""

    state: np.ndarray
    stats: dict
    occupancy: np.ndarray

    @property
    def visible(self):
        """``(n,) bool``: objects not culled."""
        return self.state == Visibility.VISIBLE
