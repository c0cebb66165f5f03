"""Every tolerance of the engine in one place, each with the reason for its value.

All CPU math is float64 and camera-relative (positions minus the eye) before
anything is rounded to float32 for the GPU, so tolerances are relative to the
magnitudes they guard.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class Tolerance:
    # Plane tests: a box is rejected only when it is outside a frustum plane by
    # more than this fraction of its own camera-relative magnitude.  float64
    # carries ~1e-16 relative error per operation; 1e-9 leaves a wide margin
    # for the handful of operations in a plane distance.
    plane_rel: float = 1e-9
    # Query boxes are grown by this fraction of (distance to eye + box size)
    # before they are rounded to float32 (relative precision 6e-8) and
    # rasterised against a 24-bit depth buffer: ~16 float32 ulps, so a box
    # whose face coincides with the surface it bounds is never pushed behind it.
    box_grow_rel: float = 1e-6
    # Absolute floor for the growth above, in scene units relative to the
    # scene's size (a zero-thickness object at the origin still gets a box).
    box_grow_scene: float = 1e-9
    # A box whose nearest point is closer to the eye than near * (1 + this) is
    # treated as crossing the near plane (visible without a query): it guards
    # the clip-space division from w values that are near zero.
    near_guard_rel: float = 1e-6


tol = Tolerance()
