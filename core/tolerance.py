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
    # Every query box grows by at least this many query pixels, measured at its
    # farthest point (so by at least as much everywhere on screen): a box whose
    # projection covers no pixel centre of this renderer but would cover one of
    # a renderer that samples up to half a pixel away (another GPU, another
    # rasteriser's rounding, the viewport) is still tested at a centre it reaches.
    # The query decides alone, so its answer must not hang on sample rounding.
    query_guard_px: float = 0.5
    # Bits of the depth buffer the queries test against (moderngl's depth
    # textures and renderbuffers are DEPTH_COMPONENT24).
    depth_bits: int = 24
    # Query boxes also grow by this many depth-buffer steps at their distance:
    # the occluder's stored depth and the box fragment's depth are each rounded
    # to the 24-bit grid (half a step each), and each is computed in float32 on
    # its own path (an MVP rounded to float32, a 4-term product, the division by
    # w): near the far plane, where the window depth is within 1e-4 of 1, that
    # alone puts a surface up to about 2 steps nearer or farther than it is
    # (1.9 measured on the city-xl path, a wall seen edge-on 270 units away with
    # far 360), for each of the two surfaces compared.  1 + 2 x 2 plus a step of
    # margin: a surface tied with the occluder (ties count as visible), such as
    # an object's box against the object's own depth, is never pushed behind it
    # by rounding (tests/test_gpu_strategy.py::test_far_wall_against_its_own_depth).
    # Perspective: one step in eye-space depth at distance d is
    # d^2 (far - near) / (near far 2^bits); orthographic: (far - near) / 2^bits.
    depth_guard_steps: float = 6.0
    # The coherent strategies' memory of last pass's visible leaves is used only
    # when the camera moved less than this fraction of the scene's size ...
    coherence_move_rel: float = 0.01
    # ... and turned less than this many degrees, with the same projection
    # (relative change of any entry below 1e-9); otherwise the pass starts fresh
    # (a camera cut or a sparse pass: memory would keep visible what a fresh
    # pass hides).
    coherence_turn_deg: float = 3.0
    coherence_projection_rel: float = 1e-9
    # The guard's floors (CullPass.guard and its GLSL twin, core/gl/glsl/guard.glsl):
    # of a division by a length, and of the nearest eye depth relative to the farthest
    # corner's distance (a box whose nearest point is at the eye still grows finitely).
    guard_tiny: float = 1e-300
    guard_near_w_rel: float = 1e-12
    # The floor of every other divisor that is a length, an area or a scale: never 0, far
    # below any that a scene holds, so a degenerate one divides to a huge finite value.
    tiny: float = 1e-300


tol = Tolerance()
