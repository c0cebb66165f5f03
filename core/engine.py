"""The engine's face: a :class:`Culler` holds a scene on the GPU and culls it from cameras.

    culler = Culler(scene, resolution=(640, 360), strategy="om_multi")
    result = culler.cull(camera)           # CullResult: state (n,) uint8, stats (PassStats)
    truth = culler.truth(camera)           # (n,) bool, exact at this resolution
"""

import dataclasses
import time
import warnings
from copy import copy
from types import SimpleNamespace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .bounds import MAX, MIN
from .camera import Camera
from .cull import DEFAULT_STRATEGY, REGISTRY, CullPass, CullResult, PassStats, Visibility, make_strategy
from .envelope import Envelope, ImageSchedule, envelope_pass, floor_cut
from .errors import OccError
from .hierarchy import build_hierarchy
from .scene import Scene
from .settings import CullOptions, check_resolution
from .subdivision import build_tree
from .units import ChunkCache, chunked, whole_objects

Resolution = tuple[int, int]
DEFAULT_RESOLUTION = (640, 360)


def parse_resolution(text):
    """``"WxH"`` -> ``(W, H)`` with a clear error."""
    try:
        w, h = (int(x) for x in str(text).lower().split("x"))
    except ValueError:
        raise OccError(f"resolution must look like 640x360, got '{text}'") from None
    return check_resolution((w, h))[0]


# The box of a unit that must never be reached (NaN or infinite values): the
# identity of box union, so its ancestors' boxes are those of their valid
# children, and outside every frustum plane by ~1e300 (no overflow in a plane test).
EMPTY_BOX = np.array([[1e300] * 3, [-1e300] * 3])
# The world matrix the renderer holds for an object that must never be drawn (NaN or
# infinite values, cut by a clipping region): every vertex at the clip-space origin, so
# no triangle covers a pixel even where a strategy draws a whole subtree unchecked.
NEVER_DRAWN = np.zeros((4, 4))
WARN_NAMES = 5           # names listed in the warning about invalid objects


def _scene_size(bounds):
    """Largest coordinate or extent of the scene (the depth range's scale)."""
    bounds = bounds[np.isfinite(bounds).all(axis=(1, 2))]
    if not len(bounds):
        return 1.0
    ext = bounds[:, MAX].max(axis=0) - bounds[:, MIN].min(axis=0)
    return float(max(np.abs(bounds).max(), ext.max()))


def _same_structure(previous, scene, units):
    """Whether ``units`` of ``scene`` fit the previous hierarchy leaf for leaf."""
    old, ou = previous.scene, previous.units
    return (previous.hierarchy is not None and len(old) == len(scene)
            and np.array_equal(old.tree_parent, scene.tree_parent)
            and np.array_equal(old.tree_object, scene.tree_object)
            and np.array_equal(ou.object, units.object)
            and all(a is b for a, b in zip(ou.trees, units.trees, strict=True)))


def make_units(scene, builder="tree", chunk_triangles=None, chunk_min_triangles=None, cache=None):
    """Draw units of a scene: whole objects, or chunks of meshes heavier than
    ``chunk_min_triangles`` (default 4 x chunk_triangles), built with ``builder``
    (pHBVO inside meshes when the builder is "tree"); ``cache``: a
    :class:`core.units.ChunkCache` of earlier chunkings to reuse.  A mesh with
    NaN or infinite values is never chunked."""
    if not chunk_triangles:
        return whole_objects(scene)
    leaf = int(chunk_triangles)
    minimum = int(chunk_min_triangles or 4 * leaf)
    inner = "pHBVO" if builder == "tree" else builder
    return chunked(scene, lambda m, tris: tris >= minimum and scene.mesh_valid[m],
                   lambda boxes: build_tree(boxes, inner, leaf_size=leaf, max_children=4, pull_up=True),
                   cache=cache)


class Culler:
    """A scene uploaded once, culled from any number of cameras.

    resolution: query resolution ``(W, H)``; strategy: a name of
    :data:`core.cull.STRATEGIES`; options: :class:`core.settings.CullOptions`
    (occupancy tiles, visible threshold, pixel guard, chunk); max_tests: first
    frame's stage-2 rounds of om_multi; max_children: widest inner node;
    exact_bounds: object boxes from transformed vertices instead of transformed
    mesh boxes (tighter for rotated objects, slower to build); hierarchy: "tree"
    (the scene's own tree above objects) or a builder of
    :data:`core.subdivision.BUILDERS` (above objects, and inside chunked meshes);
    chunk_triangles: cut meshes of more than ``chunk_min_triangles`` triangles
    into chunks of about this many triangles (None: never); chunk_cache: a
    :class:`core.units.ChunkCache` shared with earlier cullers of the same
    hierarchy and chunk settings, whose chunkings of unchanged meshes are reused;
    display: the display resolution ``(W, H)`` when it is above the query
    resolution: the renderer then takes each query pixel's occluder depth as the
    farthest of the display pixels it stands for, so a gap open on the display is
    never closed by the query (where the renderer supports it; see
    :attr:`conservative_display`); query_pixels: count the pixels each query box
    rasterises (``PassStats.query_raster_pixels``, the 2003 paper's figure, which the
    bench reports): a projection of every box tested, which a caller that never reads
    it (the add-on) leaves off.

    Objects with NaN or infinite values (``scene.invalid``) are kept VISIBLE,
    never drawn as occluders, and named in a warning and in ``invalid_names``.
    """

    def __init__(self, scene: Scene, resolution: Resolution = DEFAULT_RESOLUTION, strategy: str = DEFAULT_STRATEGY,
                 options: CullOptions | None = None, max_tests: int = 8, max_children: int = 8,
                 exact_bounds: bool = False, hierarchy: str = "tree", chunk_triangles: int | None = None,
                 chunk_min_triangles: int | None = None, ctx=None, chunk_cache: ChunkCache | None = None,
                 display: Resolution | None = None, query_pixels: bool = True) -> None:
        self.resolution, shown = check_resolution(resolution, display)
        self.query_pixels = query_pixels
        self.display = None if display is None else shown
        self.strategy_name = strategy
        self.max_tests = max_tests
        self.strategy = make_strategy(strategy, max_tests)
        self.options = options or CullOptions()
        self.exact_bounds = exact_bounds
        self.hierarchy_builder = hierarchy
        self.max_children = max_children
        self.chunking = (chunk_triangles, chunk_min_triangles)
        self.chunk_cache = chunk_cache if chunk_cache is not None else ChunkCache()
        self._unit_bounds_memo: tuple | None = None
        self._build(scene, ctx)

    def _build(self, scene, ctx, previous=None):
        t = time.perf_counter()
        self.scene = scene
        self.envelope_occluders = None     # what the next envelope pass draws (None: every object)
        self.envelope_image = ImageSchedule()   # whether it draws its image at all
        # each mesh's convex polygons (core.umbra), found by the envelope pass once per mesh of
        # this scene: keyed by mesh index, so never by identity (Python reuses a freed array's
        # id, and a memo that outlived its scene once lent an old mesh's faces to a new one)
        self.mesh_polygons: dict[int, np.ndarray] = {}
        self.units = make_units(scene, self.hierarchy_builder, *self.chunking, cache=self.chunk_cache)
        self.scene_size = _scene_size(scene.bounds)
        self._warn_invalid()
        refit = previous is not None and _same_structure(previous, scene, self.units)
        if refit:              # the same objects, tree and chunk subtrees: the old hierarchy, refitted
            self.hierarchy = copy(previous.hierarchy)
            self.hierarchy.bounds = self.hierarchy.bounds.copy()
            self.hierarchy.refit(self.unit_bounds())
        else:
            object_tree = None
            if self.hierarchy_builder != "tree" and len(scene):
                ob, ok = scene.bounds, ~scene.invalid
                # invalid objects: a point at the scene's middle (the refit below gives them no extent)
                ob[~ok] = 0.5 * (ob[ok].min(axis=(0, 1)) + ob[ok].max(axis=(0, 1))) if ok.any() else 0.0
                object_tree = build_tree(ob, self.hierarchy_builder, leaf_size=1,
                                         max_children=max(2, self.max_children), pull_up=False)
            self.hierarchy = build_hierarchy(self.unit_bounds(), self.units.of_object, scene.tree_parent,
                                             scene.tree_object, self.max_children, self.units.trees, object_tree)
        with np.errstate(invalid="ignore", over="ignore"):       # invalid objects: replaced just below
            self.renderer = self._renderer(scene, ctx)
        if scene.invalid.any():
            bad = np.flatnonzero(scene.invalid)
            self.renderer.set_matrices(bad, np.repeat(NEVER_DRAWN[None], len(bad), axis=0))
        self.build_info = {"build_ms": 1e3 * (time.perf_counter() - t), "hierarchy": "refitted" if refit else "built",
                           "meshes_chunked": self.chunk_cache.misses, "chunkings_reused": self.chunk_cache.hits}

    def _renderer(self, scene, ctx):
        from .gl import GLRenderer  # the GPU backend is the only moderngl user
        if self.display is not None and self.display != self.resolution:
            try:
                return GLRenderer(scene, *self.resolution, ctx=ctx, units=self.units, display=self.display)
            except TypeError:           # a renderer without the conservative lower resolution
                pass
        return GLRenderer(scene, *self.resolution, ctx=ctx, units=self.units)

    @property
    def conservative_display(self):
        """Whether the queries answer for the display resolution (``display`` given and
        supported by the renderer), not only for the query resolution."""
        return self.display is None or self.display == self.resolution or \
            getattr(self.renderer, "display", None) is not None

    @property
    def invalid_names(self):
        """Names of the objects kept visible because of NaN or infinite values."""
        return self.scene.invalid_names

    def _warn_invalid(self):
        names = self.scene.invalid_names
        if names:
            shown = ", ".join(f"'{x}'" for x in names[:WARN_NAMES])
            more = f" and {len(names) - WARN_NAMES} more" if len(names) > WARN_NAMES else ""
            warnings.warn(f"objects with NaN or infinite values in their matrix or vertices are kept "
                          f"visible and not used as occluders: {shown}{more}", stacklevel=3)

    def structure_mb(self):
        """Memory held by the culling structure (hierarchy, draw units, chunk orders), MiB."""
        h, u = self.hierarchy, self.units
        arrays = [u.object, u.first, u.count, u.local_bounds, *[o for o in u.face_order if o is not None]]
        if h is not None:
            arrays += [h.bounds, h.first_child, h.child_count, h.leaf_unit, h.parent, h.depth]
        return sum(a.nbytes for a in arrays) / 2**20

    def replace_scene(self, scene: Scene) -> None:
        """A new version of the scene (objects added, removed or edited), on the same
        GL context and settings.  Meshes that are the very same arrays as before keep
        their chunk subtrees (see :class:`core.units.ChunkCache`); when the objects,
        the scene tree and every object's chunk subtree are the same, the hierarchy is
        the old one refitted to the new boxes.  An edit costs the edited meshes'
        chunking and the upload, not a rebuild of every heavy mesh.  ``build_info``
        tells what was redone."""
        old = self.renderer
        kept = {k: getattr(self, k) for k in ("scene", "units", "scene_size", "hierarchy", "renderer", "build_info")}
        previous = SimpleNamespace(**kept)
        try:
            self._build(scene, old.ctx, previous)
        except BaseException:
            self.__dict__.update(kept)          # a bad scene leaves the engine as it was
            raise
        self.renderer.own_ctx, old.own_ctx = old.own_ctx, False     # the context moves to the new renderer
        old.release()
        self.strategy = make_strategy(self.strategy_name, self.max_tests)   # coherence across scenes means nothing

    def __len__(self):
        return len(self.scene)

    def set_strategy(self, name: str, max_tests: int = 8) -> None:
        """Switch strategy without re-uploading the scene."""
        self.strategy = make_strategy(name, max_tests)
        self.strategy_name, self.max_tests = name, max_tests

    def set_options(self, options: CullOptions) -> None:
        """New accuracy settings (tiles, threshold, guard, chunk) for the next passes."""
        self.options = options

    def forget(self, everything: bool = False) -> None:
        """A fresh pass is asked (a click, a camera cut, a scene edit): the strategy drops
        what it learnt that could cost accuracy (:meth:`core.cull.Strategy.forget`), or,
        with ``everything``, all of it (the next pass is a new engine's first)."""
        self.envelope_occluders = None
        self.envelope_image.reset()
        if everything:
            self.strategy.reset()
        else:
            self.strategy.forget()

    def set_matrices(self, indices: ArrayLike, matrices: ArrayLike) -> None:
        """Objects moved: new world matrices ``(k, 4, 4)`` for ``indices``; refits the hierarchy."""
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        m = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        if len(idx) != len(m):
            raise OccError(f"{len(idx)} indices but {len(m)} matrices")
        bad = ~np.all(np.isfinite(m), axis=(1, 2))
        was = self.scene.invalid[idx].copy()
        self.scene.matrices[idx] = m
        self.scene.invalid[idx] = bad | ~self.scene.mesh_valid[self.scene.mesh_of[idx]]
        if (self.scene.invalid[idx] & ~was).any():
            self._warn_invalid()
        # never drawn (see unit_bounds, NEVER_DRAWN); no NaN in the GPU's arrays
        self.renderer.set_matrices(idx, np.where(bad[:, None, None], NEVER_DRAWN, m))
        self.strategy.moved(idx)          # what was visible before the move proves nothing now
        if self.envelope_occluders is not None:
            self.envelope_occluders[idx] = True     # a moved object may stand in front now
        if self.hierarchy is not None:
            self.hierarchy.refit(self.unit_bounds())

    def unit_bounds(self) -> NDArray[np.float64]:
        """World boxes of the draw units, ``(u, 2, 3)``; :data:`EMPTY_BOX` for the
        units of invalid objects.  A new array each call; the last answer is kept while
        the scene, its units, matrices and invalid objects are the same (value for value;
        not with ``exact_bounds``, whose vertices are read afresh)."""
        scene = self.scene
        memo = self._unit_bounds_memo
        if memo is not None and memo[0] is scene and memo[1] is self.units and not self.exact_bounds \
                and np.array_equal(memo[2], scene.matrices) and np.array_equal(memo[3], scene.invalid):
            return memo[4].copy()
        # computed from copies of the matrices, kept with them: a matrix changed in place
        # (even during this call) is a new answer
        matrices, invalid = scene.matrices.copy(), scene.invalid.copy()
        ub = self.units.world_bounds(np.where(invalid[:, None, None], np.eye(4), matrices))
        if self.exact_bounds:
            whole = np.flatnonzero([t is None for t in self.units.trees] & ~invalid)
            if len(whole):
                ub[np.concatenate([self.units.of_object[o] for o in whole])] = self.scene.exact_bounds()[whole]
        ub[invalid[self.units.object]] = EMPTY_BOX
        self._unit_bounds_memo = (scene, self.units, matrices, invalid, ub.copy())
        return ub

    def truth(self, camera: Camera) -> NDArray[np.bool_]:
        """Exact visible set at the query resolution from an object-ID buffer, ``(n,) bool``.

        Invalid objects (NaN or infinite values) count as visible: nothing can be
        known about them, and the engine keeps them."""
        invalid = self.scene.invalid
        if not invalid.any():
            return self.renderer.visible_truth(camera)
        ids = self.renderer.object_ids(camera, np.flatnonzero(~invalid))
        out = invalid.copy()
        out[ids[ids >= 0]] = True
        return out

    def cull(self, camera: Camera, truth: NDArray[np.bool_] | None = None, fresh: bool = False,
             envelope=None, lights=None, probe: bool = True, clip: ArrayLike | None = None) -> CullResult:
        """One culling pass from ``camera``; ``truth`` is needed by the oracle only;
        ``fresh``: forget what earlier passes taught the strategy (its answer is
        then that of a new engine's first pass); ``envelope``: ``(D, A)`` or a
        :class:`core.envelope.Envelope`: hide only what is hidden from every view
        whose eye is within ``D`` of the camera's and whose direction is within ``A``
        degrees of its direction (same lens, any roll); see :mod:`core.envelope`.
        The strategy does not change that answer, only the point pass's.
        ``lights``: :class:`core.lights.Light` of a lit view: an object also stays
        while its shadow may fall on something seen (an envelope pass, of ``(0, 0)``
        when no envelope is given).  ``probe``: an envelope pass may draw its image only
        to learn whether it helps (:class:`core.envelope.ImageSchedule`; False during
        motion).  ``clip``: ``(k, 4)`` planes ``(a, b, c, d)`` of a clipping region (a
        3D view's Alt+B box): the view draws only where ``a x + b y + c z + d > 0`` for
        every plane; an object whose box is not wholly inside is drawn cut or not at
        all, so it is kept VISIBLE and never drawn as an occluder (see :meth:`clipped`)."""
        cut = self.clipped(clip)
        if cut is None or not cut.any():
            return self._cull(camera, truth, fresh, envelope, lights, probe)
        was = self.scene.invalid.copy()
        self._left_out(was | cut)
        try:
            with np.errstate(over="ignore"):          # the empty boxes' projections (never drawn)
                result = self._cull(camera, truth, fresh, envelope, lights, probe)
        finally:
            self._left_out(was)
        result.stats.invalid_objects = int(was.sum())
        result.stats.clipped_objects = int((cut & ~was).sum())
        return result

    def clipped(self, clip: ArrayLike | None) -> NDArray[np.bool_] | None:
        """``(n,) bool``: the objects whose world box is not wholly inside the clipping
        region ``clip`` (planes as in :meth:`cull`; a plane with no normal is none), with
        a margin of a millionth of the scene's size; None without planes."""
        if clip is None:
            return None
        planes = np.asarray(clip, dtype=np.float64).reshape(-1, 4)
        if not np.isfinite(planes).all():
            raise OccError("the clipping region's planes hold NaN or infinite values")
        length = np.linalg.norm(planes[:, :3], axis=1)
        planes = planes[length > 0.0] / length[length > 0.0, None]
        if not len(planes):
            return None
        b = self.scene.bounds
        centre, half = 0.5 * (b[:, MIN] + b[:, MAX]), 0.5 * (b[:, MAX] - b[:, MIN])
        with np.errstate(invalid="ignore", over="ignore"):   # invalid objects: left out anyway
            nearest = centre @ planes[:, :3].T - half @ np.abs(planes[:, :3]).T + planes[:, 3]
            inside = (nearest > 1e-6 * self.scene_size).all(axis=1)
        return ~inside

    def _left_out(self, invalid):
        """Make ``invalid`` the objects that are kept visible and never drawn (their
        boxes empty in the hierarchy, the strategy told they moved)."""
        changed = np.flatnonzero(self.scene.invalid != invalid)
        if not len(changed):
            return
        self.scene.invalid[:] = invalid
        self.renderer.set_matrices(changed, np.where(invalid[changed, None, None], NEVER_DRAWN,
                                                     self.scene.matrices[changed]))
        self.strategy.moved(changed)
        if self.hierarchy is not None:
            self.hierarchy.refit(self.unit_bounds())

    def _cull(self, camera, truth, fresh, envelope, lights, probe):
        n = len(self.scene)
        if envelope is not None or lights:
            if fresh:
                self.envelope_occluders = None
                self.envelope_image.reset()
            return self._envelope_cull(camera, (0.0, 0.0) if envelope is None else envelope, lights, probe)
        if fresh:
            self.strategy.reset()
        if self.hierarchy is None:
            empty = np.zeros(0, dtype=np.uint8)
            return CullResult(empty, self._count(empty, PassStats()), np.zeros((0, 0), bool))
        if REGISTRY[self.strategy_name].needs_truth and truth is None:
            truth = self.truth(camera)
        cp = CullPass(self.hierarchy, self.renderer, camera, self.options, self.scene_size, self.query_pixels)
        self.strategy(cp, chunk=self.options.chunk, truth=truth)
        stats = cp.finish()
        state = cp.object_state()
        invalid = self.scene.invalid
        state[invalid] = Visibility.VISIBLE       # conservative: nothing is known about them
        stats.invalid_objects = int(invalid.sum())
        self._count(state, stats)
        assert len(state) == n
        return CullResult(state, stats, cp.om.grid.copy())

    def _envelope_cull(self, camera, envelope, lights=None, probe=True):
        if not isinstance(envelope, Envelope):
            envelope = Envelope(*envelope)
        if envelope.above_floor and envelope.floor is None and not camera.is_orthographic:
            floor = floor_cut(self, camera.eye, envelope.distance)
            if floor is not None:                      # the pass's envelope (its result carries it)
                envelope = dataclasses.replace(envelope, floor=floor)
        image = self.envelope_image.draws(probe)
        state, stats = envelope_pass(self, camera, envelope, lights=lights, occluders=self.envelope_occluders,
                                     image=image)
        if stats.envelope_image_hidden is not None:
            self.envelope_image.drew(stats.envelope_image_hidden)
        # the next envelope pass draws as occluders only what this one did not prove hidden
        self.envelope_occluders = state != Visibility.OCCLUDED
        self._count(state, stats)
        return CullResult(state, stats, np.zeros((0, 0), bool), envelope)

    def scene_bounds(self) -> NDArray[np.float64]:
        """``(2, 3)``: the box of every valid object (where any shadow can fall)."""
        ok = ~self.scene.invalid
        if not ok.any():
            return np.zeros((2, 3))
        b = self.scene.bounds[ok]
        return np.array([b[:, MIN].min(axis=0), b[:, MAX].max(axis=0)])

    def _count(self, state, stats):
        """The answer's figures into ``stats``."""
        tri = self.scene.triangle_counts
        stats.objects = int(len(state))
        stats.visible = int((state == Visibility.VISIBLE).sum())
        stats.occluded = int((state == Visibility.OCCLUDED).sum())
        stats.view_culled = int((state == Visibility.VIEW_CULLED).sum())
        stats.triangles_total = int(tri.sum())
        stats.triangles_visible = int(tri[state == Visibility.VISIBLE].sum())
        return stats

    def close(self) -> None:
        self.renderer.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
