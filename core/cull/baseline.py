"""The strategy interface and the baselines: frustum culling alone, the oracle, and
the papers' one-query-at-a-time traversals."""

import heapq

import numpy as np
from numpy.typing import NDArray

from ..errors import OccError
from .result import Visibility
from .view_pass import CullPass


class Strategy:
    """What every strategy is: called once per pass on a :class:`CullPass`, it draws what
    it finds visible, marks what it proves occluded and counts in ``cp.stats``.

    What it keeps between passes is its own, and three calls tell it what changed:

    - :meth:`reset`: everything learnt is void (a new scene, ``cull(fresh=True)``): the
      next pass is a new engine's first;
    - :meth:`forget`: a fresh pass is asked (the add-on: a click, a camera cut, an edit):
      drop what could cost accuracy, keep what only orders the work;
    - :meth:`moved`: objects moved: drop what their old places proved.

    By default each drops everything.  A strategy that keeps nothing is stateless.
    """

    def __call__(self, cp: CullPass, chunk: int = 16, truth: NDArray[np.bool_] | None = None) -> None:
        raise NotImplementedError

    def reset(self) -> None:
        """Everything learnt is void: the next pass is a new engine's first."""

    def forget(self) -> None:
        """A fresh pass is asked: by default, :meth:`reset`."""
        self.reset()

    def moved(self, objects: NDArray[np.int64] | None = None) -> None:
        """Objects moved (``objects``: their indices, None: any): by default, :meth:`reset`."""
        self.reset()


class Vfc(Strategy):
    def __call__(self, cp, chunk=16, truth=None):
        cp.draw_leaves(cp.frustum_leaves())


class Oracle(Strategy):
    def __call__(self, cp, chunk=16, truth=None):
        if truth is None:
            raise OccError("the oracle strategy needs the ground-truth visible set")
        h = cp.tree
        leaves = cp.frustum_leaves()
        # a chunk of a truly visible object is drawn: the truth is per object
        seen = truth[cp.unit_object[h.leaf_unit[leaves]]]
        cp.ensure_geometry(leaves[seen])
        cp.draw_leaves(cp.sort_near(leaves[seen]))
        cp.state[h.leaf_unit[leaves[~seen]]] = Visibility.OCCLUDED


class StopWait(Strategy):
    """One query per node, answer awaited before the next (the baseline to beat)."""

    def __call__(self, cp, chunk=16, truth=None):
        h = cp.tree
        if not len(cp.root()):
            return
        heap = [(cp.dist[0], 0)]
        while heap:                        # per node by design: this is the slow baseline
            _, node = heapq.heappop(heap)
            one = np.array([node])
            if not cp.crosses[node]:
                if not cp.query(one)[0]:
                    cp.occlude(one)
                    continue
            else:
                cp.stats.near_visible += 1
            if h.is_leaf[node]:
                cp.draw_leaves(one)
            else:
                for c in cp.children_in_frustum(one):
                    heapq.heappush(heap, (cp.dist[c], int(c)))


class LeafStopWait(Strategy):
    """The leaves in the frustum front to back, one awaited query each (no
    hierarchy above them, no occupancy map)."""

    use_map = False

    def __call__(self, cp, chunk=16, truth=None):
        leaves = cp.frustum_leaves()
        cp.ensure_geometry(leaves)
        for leaf in cp.sort_near(leaves):     # per leaf by design: a baseline
            one = np.array([leaf])
            if cp.crosses[leaf]:
                cp.stats.near_visible += 1
            elif self.use_map and cp.om.any_empty_tiles(cp.tiles[one])[0]:
                cp.stats.queries_skipped += 1
            elif not cp.query(one)[0]:
                cp.occlude(one)
                continue
            cp.draw_leaves(one)


class OmSingle(LeafStopWait):
    """Staneker et al. 2003 with single queries: leaves front to back; a leaf
    whose rectangle still has an empty tile is drawn without a query, any other
    gets its own query, awaited before the next leaf."""

    use_map = True
