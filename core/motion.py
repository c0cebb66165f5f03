"""Live culling while the view moves: the policy that sizes a pass's envelope and
says when the displayed set must go.

A pass hides a set that holds for an envelope around the view it was made from
(:mod:`core.envelope`).  The policy sizes the envelope from the measured motion: the
eye's speed and the turn rate, times the time until the pass lands plus how long it
should last after, plus a margin of a few steps of motion.  Before each redraw the
view is checked against the displayed set's envelope, with room for the next step:
a view about to leave it shows everything first (showing is urgent), and a new pass
starts from where the view is; its set is shown when it lands, if the view is still
inside its envelope.  At rest the envelope is small (:attr:`LivePolicy.rest_rel`,
:attr:`LivePolicy.rest_deg`): the first steps of a new motion stay in it, and the
check before the next redraw catches the rest.

The benchmark that replays motions under this policy is :mod:`core.lab.motion`
(``python -m core motion SCENE``).
"""

import math
from dataclasses import dataclass

import numpy as np

from .envelope import Envelope

MAX_ANGLE_DEG = 30.0         # a wider envelope hides little; a faster turn shows all until it slows


@dataclass(frozen=True)
class LivePolicy:
    """How big an envelope a pass takes and when the displayed set must go."""

    hold_s: float = 0.5          # the envelope lasts this long after the pass lands, at the measured speed
    margin_steps: float = 2.0    # and this many steps of the last motion beyond that
    rest_rel: float = 0.002      # the envelope at rest: this share of the scene's size ...
    rest_deg: float = 2.0        # ... and this many degrees

    def envelope(self, speed, turn_deg_s, latency_s, step_move, step_turn_deg, scene_size):
        """The envelope of a pass that lands ``latency_s`` from now, the view moving at
        ``speed`` (scene units per second) and turning ``turn_deg_s``."""
        horizon = latency_s + self.hold_s
        d = max(speed * horizon + self.margin_steps * step_move, self.rest_rel * scene_size)
        a = max(turn_deg_s * horizon + self.margin_steps * step_turn_deg, self.rest_deg)
        # the turn measured is the frame's (roll included): a narrower view than any roll
        return Envelope(d, min(a, MAX_ANGLE_DEG), any_roll=False)

    def rest(self, scene_size):
        """The envelope of a pass made at rest: what the first steps of a motion need
        before the check before each redraw sees them."""
        return Envelope(self.rest_rel * scene_size, self.rest_deg, any_roll=False)

    def safe(self, centre, envelope, view, step_move, step_turn_deg):
        """Whether ``view`` and the next step (as large as ``margin_steps`` of the last)
        stay inside ``envelope`` around ``centre``."""
        if not np.array_equal(centre.projection, view.projection):
            return False                                          # another lens: the envelope says nothing
        move, turn = view_change(centre, view, frame=not envelope.any_roll)
        return (move + self.margin_steps * step_move <= envelope.distance
                and turn + self.margin_steps * step_turn_deg <= envelope.angle_deg)


def view_change(a, b, frame=True):
    """Eye distance and turn (degrees) between two cameras: the angle of the rotation
    from one camera frame to the other (roll included), or with ``frame=False`` only
    the angle between their view directions."""
    move = float(np.linalg.norm(a.eye - b.eye))
    if frame:
        ra, rb = a.view[:3, :3], b.view[:3, :3]
        ra = ra / np.linalg.norm(ra, axis=1, keepdims=True)      # rows: the camera's axes
        rb = rb / np.linalg.norm(rb, axis=1, keepdims=True)
        cos = float(np.clip((np.trace(ra @ rb.T) - 1.0) / 2.0, -1.0, 1.0))
    else:
        cos = float(np.clip(a.direction @ b.direction, -1.0, 1.0))
    return move, math.degrees(math.acos(cos))
