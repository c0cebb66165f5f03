"""The coherent strategies' memory (``om_coherent``, ``two_pass``): last pass's visible
leaves, drawn first in the next pass without a test (after Bittner et al.'s CHC)."""


from ..camera import camera_cut
from .result import Visibility


class CoherentMemory:
    """Which leaves were visible in the last pass, kept while the camera barely moves.

    A camera cut (:func:`core.camera.camera_cut`) drops it; :meth:`leaves` leaves out
    one leaf in ``RECHECK`` per pass (staggered by node index), so a remembered leaf
    that became hidden is tested again, and culled, within ``RECHECK`` passes.  The
    memory only skips tests of leaves that are then drawn, never culls: conservative.
    """

    RECHECK = 8

    def __init__(self):
        self.seen = None          # (nodes,) bool: leaves visible in the last remembered pass
        self.last_camera = None
        self.passes = 0           # remembered passes: staggers the rechecks

    def reset(self):
        self.seen = None
        self.last_camera = None

    def start(self, cp):
        """At a pass's start: forget after a camera cut (the pass counts as fresh)."""
        if camera_cut(self.last_camera, cp.camera, cp.scene_size):
            self.seen = None
            cp.stats.fresh = 1
        self.last_camera = cp.camera

    def holds(self, cp):
        """Whether there is memory for this pass's tree."""
        return self.seen is not None and len(self.seen) == len(cp.tree) and bool(self.seen.any())

    def leaves(self, nodes):
        """``(k,) bool``: which of ``nodes`` to draw without a test this pass."""
        return self.seen[nodes] & ((nodes + self.passes) % self.RECHECK != 0)

    def remember(self, cp):
        """The visible leaves of the pass that just ran."""
        tree = cp.tree
        seen = tree.is_leaf & cp.in_frustum
        seen[seen] = cp.state[tree.leaf_unit[seen]] == Visibility.VISIBLE
        self.seen = seen
        self.passes += 1
