"""The occupancy-map strategies: ``om`` (2003), ``om_multi`` and ``om_coherent``
(2004, with this project's temporal coherence), and ``two_pass``."""

import math

import numpy as np

from .baseline import Strategy
from .memory import CoherentMemory
from .stages import frustum_leaves_below, resolve, stage1, test_list

OM_MAX_BATCHES = 5
COHERENT_READS = 5             # read-backs a pass of om_coherent (and auto): a GPU round trip each


class Om(Strategy):
    """Staneker et al. 2003 over the leaves of the frustum, remaining queries batched."""

    def __call__(self, cp, chunk=16, truth=None):
        leaves = cp.frustum_leaves()
        cp.ensure_geometry(leaves)
        pending = stage1(cp, leaves, chunk)
        for batch in range(OM_MAX_BATCHES):
            if not len(pending):
                break
            pending = cp.sort_near(pending)
            if batch == OM_MAX_BATCHES - 1:
                test, pending = pending, pending[:0]
            else:
                test, pending = test_list(cp, pending)
            resolve(cp, test, cp.query(test))


class OmMulti(Strategy):
    """Staneker et al. 2004; keeps ``max_tests`` across frames (the 0.7 m rule).

    With ``coherent`` (this project's addition, after Bittner et al.'s CHC): the
    leaves found visible last pass are drawn first, without a query, and their
    ancestors are opened without one; each such leaf is queried again every
    ``CoherentMemory.RECHECK`` passes (staggered), so one that became hidden is culled soon.
    Only skipping queries, never culling without one, it stays conservative.

    ``read_budget`` (this project's, for the coherent default): at most that many
    multiple queries, hence blocking read-backs, a pass -- stage 2 gets all but two
    of them, and stage 3 asks what remains in one batch and then every leaf below
    the visible ones in another, instead of level by level.
    The memory is used only when the camera barely moved since the last pass
    (:func:`core.camera.camera_cut`): after a cut, or a sparse pass (the add-on's), the pass
    starts fresh, so memory never makes a pass worse than a fresh one by more
    than what the last small move uncovered.
    """

    def __init__(self, max_tests=8, coherent=False, read_budget=None):
        self.first_max_tests = self.max_tests = max(1, int(max_tests))
        self.coherent = coherent
        self.read_budget = read_budget
        self.memory = CoherentMemory()

    def __call__(self, cp, chunk=16, truth=None):
        if self.coherent:
            self.memory.start(cp)
        if not len(cp.root()):
            return
        if self.coherent:
            self._draw_remembered(cp)
        self._traverse(cp, chunk)
        if self.coherent:
            self.memory.remember(cp)

    def reset(self):
        """Drop the memory of visible leaves and the rounds learnt (objects moved, or a
        fresh pass asked): the next pass is a new engine's first, whatever came before."""
        self.memory.reset()
        self.max_tests = self.first_max_tests

    def _draw_remembered(self, cp):
        if not self.memory.holds(cp):
            return
        pre = np.flatnonzero(self.memory.seen)
        pre = cp.reach(pre[self.memory.leaves(pre)])
        cp.draw_leaves(cp.sort_near(pre))
        cp.predrawn[pre] = True
        cp.stats.queries_skipped += len(pre)
        up = pre
        while len(up):                              # ancestors, one level per step
            cp.free[up] = True
            up = np.unique(cp.tree.parent[up])
            up = up[(up >= 0) & ~cp.free[up]]

    def _traverse(self, cp, chunk):
        pending = stage1(cp, np.zeros(1, dtype=np.int64), chunk)
        rounds = 0
        stage2 = self.max_tests if self.read_budget is None else min(self.max_tests, max(self.read_budget - 2, 0))
        # Stage 2: occupancy-map-arranged multiple queries.
        while len(pending) and rounds < stage2:
            pending = cp.sort_near(pending)
            test, pending = test_list(cp, pending)
            opened = resolve(cp, test, cp.query(test))
            pending = np.concatenate([pending, stage1(cp, opened, chunk)])
            rounds += 1
        if self.read_budget is None:
            # Stage 3: everything that remains, brute force, level by level.
            while len(pending):
                opened = resolve(cp, pending, cp.query(pending))
                pending = stage1(cp, opened, chunk)
                rounds += 1
        elif len(pending):
            # Stage 3 within the read budget: what remains in one batch, then every
            # leaf below those found visible in a second one.
            opened = resolve(cp, pending, cp.query(pending))
            rounds += 1
            # what the map proves visible below is drawn first, the rest's leaves tested
            leaves = frustum_leaves_below(cp, stage1(cp, opened, chunk))
            leaves = leaves[~cp.predrawn[leaves]]
            if len(leaves):
                resolve(cp, leaves, cp.query(leaves))
                rounds += 1
        self.max_tests = max(1, math.ceil(0.7 * rounds)) if rounds else self.max_tests


class TwoPass(Strategy):
    """GPU-driven two passes (as nvpro's temporal culling and zeux's niagara do):
    last pass's visible leaves are drawn first, without a test; every other leaf
    in the frustum is tested in ONE multiple query against that depth; of those
    that pass, the nearer half is drawn and the farther half tested once more
    against it; whatever fails a test is occluded.  A handful of GL calls and at
    most two read-backs a pass, whatever the scene's size; the per-leaf work is
    numpy over the frustum's leaves, none per node of the traversal.

    Each remembered leaf is tested again every ``CoherentMemory.RECHECK`` passes (staggered), so
    one that became hidden is culled soon; after a camera cut (see
    :func:`core.camera.camera_cut`) there is no memory, and the pass is an ``om_multi`` pass
    (the occupancy map finds the first occluders) whose visible leaves the next
    pass starts from.  Conservative: a test only fails against geometry really
    drawn.
    """

    def __init__(self, max_tests=8):
        self.memory = CoherentMemory()
        self.fresh = OmMulti(max_tests)

    def reset(self):
        self.memory.reset()
        self.fresh.reset()

    def __call__(self, cp, chunk=16, truth=None):
        self.memory.start(cp)
        if not self.memory.holds(cp):
            self.fresh(cp, chunk)                         # no memory: the occupancy map's pass
        else:
            self._two_passes(cp)
        self.memory.remember(cp)

    def _two_passes(self, cp):
        leaves = cp.frustum_leaves()
        cp.ensure_distance(leaves)
        # the recheck slot of remembered leaves is tested like the rest
        known = self.memory.leaves(leaves)
        first, rest = leaves[known], leaves[~known]
        cp.draw_leaves(cp.sort_near(first))
        cp.stats.queries_skipped += len(first)
        visible = cp.query(rest)
        cp.occlude(rest[~visible])
        passed = cp.sort_near(rest[visible])
        half = (len(passed) + 1) // 2
        cp.draw_leaves(passed[:half])
        second = passed[half:]
        visible = cp.query(second)
        cp.occlude(second[~visible])
        cp.draw_leaves(second[visible])
