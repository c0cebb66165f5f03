"""What an applied pass leaves behind: its figures (the panel, the overlay, the next
pass's latency estimate) and the view its hidden set holds for (live mode checks
every redraw against it)."""

from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..core import Camera, CullResult, PassStats, Visibility
from ..core.bounds import transform_boxes
from ..core.envelope import Envelope


class Shown(NamedTuple):
    """The view a hidden set was made from and the envelope of views it holds for;
    :data:`UNKNOWN` (both None): a hidden set of a view the session does not know."""

    camera: Camera | None
    envelope: Envelope | None


# A pass made for no envelope (a Cull click from the scene camera, live mode off)
# holds for its own view only: no move, no turn, no next step.
EXACT = Envelope(0.0, 0.0, any_roll=False)
# What an undo or redo brings back hidden was hidden for a view nobody recorded: it
# holds for no view (live mode and the redraw guard show it all before the next redraw).
UNKNOWN = Shown(None, None)


@dataclass(frozen=True, eq=False)
class LastPass:
    """The last applied pass over the engine's ``k`` objects.

    state: ``(k,) uint8`` :class:`..core.Visibility`; protected: ``(k,) bool`` never
    hidden (:mod:`.policy`); hidden_local: ``(h, 2, 3)`` the boxes of the objects it hid
    (:attr:`hidden`, in order) in their own space and hidden_matrices: ``(h, 4, 4)`` their
    world matrices then (:attr:`hidden_bounds`, the world boxes, are made from them when
    asked: the overlay, not every pass; only the hidden ones are kept); occupancy: the
    occupancy map ``(rows, cols) bool`` or None; stats: the engine's figures
    (:attr:`..core.CullResult.stats`); ms: the whole pass, Blender's update included;
    blender_ms: of it, Blender's own updates (the edits pending before the pass, and
    the hiding's); changed: how many objects' hiding the pass changed; triangles_hidden:
    of the objects it hid; rule: what the view draws and the rule it set, in words
    (:class:`.shading.ViewRule`), and rule_key: all of that rule (:func:`.shading.key`);
    drawn: ``(d,) int64`` the session ids of the objects it left drawn (the only
    ones that can hide anything: while the set stands they must stay drawn).

    The panel and the overlay show these figures from here, not from ``scene.occ``: a
    pass writes nothing to the scene but its hiding (a property written tags the scene,
    and the update it causes, after the pass, would read as the user's change).
    """

    state: np.ndarray
    protected: np.ndarray
    hidden_local: np.ndarray
    hidden_matrices: np.ndarray
    occupancy: np.ndarray | None
    stats: PassStats
    ms: float
    blender_ms: float = 0.0
    changed: int = 0
    triangles_hidden: int = 0
    rule: str = ""
    rule_key: tuple = ()
    drawn: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @cached_property
    def hidden_bounds(self) -> np.ndarray:
        """``(h, 2, 3)`` the world boxes at the pass of the objects it hid (:attr:`hidden`)."""
        if not len(self.hidden_matrices):
            return np.zeros((0, 2, 3))
        return transform_boxes(self.hidden_local, self.hidden_matrices)

    @property
    def hidden(self) -> np.ndarray:
        """``(k,) bool``: what the pass hid (or, during motion, kept hidden)."""
        return (self.state != Visibility.VISIBLE) & ~self.protected

    @property
    def tested(self) -> int:
        return len(self.state)

    @property
    def occluded(self) -> int:
        return int((self.state == Visibility.OCCLUDED).sum())

    @property
    def outside(self) -> int:
        return int((self.state == Visibility.VIEW_CULLED).sum())

    def summary(self) -> str:
        """One line of the figures (the overlay's, a Cull click's report)."""
        return (f"{self.occluded:,} occluded, {self.outside:,} outside the view, of {self.tested:,}; "
                f"{self.triangles_hidden:,} triangles hidden ({self.ms:.0f} ms)")


def shown_by(result: CullResult, camera: Camera) -> Shown:
    """The view and envelope a pass's hidden set holds for (:data:`EXACT` when the pass
    was made for no envelope: its own view only)."""
    return Shown(camera, EXACT if result.envelope is None else result.envelope)
