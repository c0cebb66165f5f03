"""The ``gpu`` strategy: the GPU-resident two passes of :mod:`core.gl.gpucull`."""

import time
import warnings

import numpy as np

from ..tolerance import tol
from .baseline import Strategy
from .occupancy_queries import COHERENT_READS, OmMulti
from .result import Visibility


class Gpu(Strategy):
    """GPU-resident two passes (nvpro's temporal culling, zeux's niagara): the units'
    boxes and matrices live on the GPU; a pass is five compute dispatches, two
    multi-draw-indirect draws and two box-test draws whose commands the GPU writes,
    and ONE read-back of every unit's state (:mod:`core.gl.gpucull`).  Pass 1 draws
    last pass's visible units (and those at the near plane); every other unit of
    the frustum is tested against a max-depth pyramid of that depth, and those that
    pass as rasterised boxes (as queries); those that pass both are drawn in pass 2;
    every drawn unit's box is then tested against the completed depth, which gives
    the states and the next pass's memory.  No per-node Python work in steady state; per unit, a few numpy
    reductions over the read-back words (the counters).

    On the first pass, and after ``reset()`` (``cull(fresh=True)``, a new scene),
    there is no memory: the pass is an ``om_coherent`` pass without memory (the
    occupancy map finds the first occluders), whose visible units the GPU then
    remembers.  Camera cuts, moved objects and the add-on's ``forget()`` keep the
    memory: it only chooses what pass 1 draws, so a cut costs drawing, never correctness.
    Conservative: a unit is OCCLUDED only when its grown box (the engine's guard) passed
    no sample against depth real geometry wrote.

    Falls back to ``om_coherent`` where the GPU path cannot run: the OpenGL 4.1 path
    (``OCC_GL=4.1``, macOS: no compute shaders, storage buffers or indirect draws),
    a ``visible_threshold`` above 0 (sample counts, not flags), or a driver whose
    compiler refuses the shaders (float64 in shaders is required); ``reason`` says
    which.  A display resolution above the query resolution is honoured (the whole
    depth is reduced before each test).
    """

    def __init__(self, max_tests=8):
        self.fallback = OmMulti(max_tests, coherent=True, read_budget=COHERENT_READS)
        self.fresh = OmMulti(max_tests, coherent=True, read_budget=COHERENT_READS)
        self.gpu = None
        self.reason = None
        self.uploaded_for = None          # (hierarchy, its bounds array) the GPU's boxes come from
        self.moved_objects = []           # objects moved since the last upload
        self.leaf_of_unit = None          # (units,) the hierarchy leaf of each unit, -1: none
        self.remembered = False
        self.last_camera = None

    def reset(self):
        """A new engine's first pass next (``cull(fresh=True)``, the add-on's Cull click):
        the memory goes.  The GPU's boxes and matrices stay: they follow the hierarchy
        (checked by identity every pass) and the objects moved (:meth:`moved`), not
        anything a pass taught, so a click does not upload every unit again."""
        self.remembered = False
        self.last_camera = None
        self.fallback.reset()

    def forget(self):
        """A fresh pass asked by the add-on (a click, a camera cut, a scene edit): the
        GPU's boxes and memory stay.  The memory only chooses what pass 1 draws and every
        state is still tested against the depth drawn, so it costs no accuracy, and a
        pass with it costs a fraction of a first pass (an ``om_coherent`` pass and a full
        upload).  The fallback's memory would cost accuracy: it goes."""
        self.fallback.reset()

    def moved(self, objects=None):
        """Objects moved: their units' boxes and matrices are uploaded again (all of
        them when ``objects`` is None or many moved); the memory is kept (it only
        chooses what pass 1 draws, at the new places; every state is still tested
        against the depth drawn), so live scenes with moving objects stay on the GPU
        path.  The fallback forgets as usual."""
        if objects is None or self.uploaded_for is None:
            self.uploaded_for = None
        else:
            self.moved_objects.append(np.asarray(objects, dtype=np.int64).reshape(-1))
        self.fallback.reset()

    def _unusable(self, cp):
        """Why this cp cannot run on the GPU path, or None."""
        if getattr(cp.renderer, "path", None) != "4.3":
            return "the OpenGL 4.1 path has no compute shaders, storage buffers or indirect draws"
        if cp.threshold > 0:
            return "a visible threshold above 0 needs sample counts"
        return None

    def _culler(self, cp):
        """The GPU side for this cp's renderer (made once per renderer), or None."""
        if self.gpu is not None and self.gpu.r is cp.renderer:
            return self.gpu
        from ..gl.gpucull import for_renderer  # the GL backend loads with the first renderer (core.gl)
        gpu, self.reason = for_renderer(cp.renderer)
        if gpu is None:
            # not the expected 4.1 fallback: a driver that refuses the shaders, said once
            warnings.warn(f"{self.reason}; the gpu strategy runs om_coherent instead", stacklevel=4)
        self.gpu, self.uploaded_for, self.remembered = gpu, None, False
        return gpu

    def __call__(self, cp, chunk=16, truth=None):
        self.reason = self._unusable(cp) or self.reason
        gpu = None if self.reason else self._culler(cp)
        if gpu is None:
            self.fallback(cp, chunk)
            return
        h = cp.tree
        if self.uploaded_for is None or self.uploaded_for[0] is not h or self.uploaded_for[1] is not h.bounds:
            self._upload(cp, gpu)
        elif self.moved_objects:
            self._upload(cp, gpu, np.unique(np.concatenate(self.moved_objects)))
        if not self.remembered:
            cp.stats.fresh = 1
            self.fresh.reset()
            self.fresh(cp, chunk)                 # no memory: the occupancy map's pass
            gpu.remember(cp.state == Visibility.VISIBLE)
            self.remembered = True
            return
        t = time.perf_counter()
        pixels = max(cp.options.pixel_guard, tol.query_guard_px, cp.reduce_guard_px)
        words = gpu.run(cp, pixels)
        cp.t_query += time.perf_counter() - t
        self._record(cp, words)

    MAX_MOVED = 16      # objects moved at once beyond which every unit is uploaded again (one write)

    def _upload(self, cp, gpu, objects=None):
        """The units' boxes (the hierarchy's leaves) and matrices to the GPU: all of
        them, or those of ``objects`` (each object's units are consecutive)."""
        h, r = cp.tree, cp.renderer
        self.moved_objects = []
        if objects is None or len(objects) > self.MAX_MOVED:
            leaves = np.flatnonzero(h.is_leaf)
            self.leaf_of_unit = np.full(len(r.units), -1, dtype=np.int64)
            self.leaf_of_unit[h.leaf_unit[leaves]] = leaves
            units = np.arange(len(r.units))
        else:
            units = np.concatenate([r.units.of_object[o] for o in objects]).astype(np.int64)
        leaf = self.leaf_of_unit[units]
        boxes = np.where((leaf >= 0)[:, None, None], h.bounds[np.maximum(leaf, 0)], 0.0)
        gpu.upload(boxes, leaf >= 0, r.world[r.units.object[units]], units)
        self.uploaded_for = (h, h.bounds)

    @staticmethod
    def _record(cp, words):
        """The states and counters of the pass from the units' words."""
        from ..gl import layout as G  # (as above: no GL module before a renderer)
        state = (words & G.STATE).astype(np.uint8)
        cp.state[:] = state
        drawn = (words & (G.DRAWN1 | G.DRAWN2)) != 0
        near = (words & G.NEAR) != 0
        tri = cp.renderer.tri_counts
        s = cp.stats
        s.units_drawn = int(drawn.sum())
        s.triangles_drawn = int(tri[drawn].sum())
        # what the pass saved: occluded and never drawn (a unit drawn and then found hidden is not)
        s.triangles_occluded = int(tri[(state == Visibility.OCCLUDED) & ~drawn].sum())
        s.queries = int(np.count_nonzero(words & G.TESTED1) + np.count_nonzero(words & G.TESTED2))
        s.multiple_queries = 2
        s.queries_skipped = int(np.count_nonzero((words & G.DRAWN1) != 0) - near.sum())
        s.near_visible = int(near.sum())
        s.nodes_visited = len(words)
