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

The motion is measured by :class:`MotionTracker`, between successive looks at the
view (live mode's redraws and ticks); the benchmark that replays motions under this
policy, with the same tracker, is :mod:`core.lab.motion` (``python -m core motion SCENE``).
"""

from dataclasses import dataclass
from enum import Enum

import numpy as np

from .camera import view_change
from .envelope import Envelope


class AtRest(Enum):
    """An envelope named before its scene is known: :meth:`LivePolicy.rest` sizes it from
    the engine's scene once that is built (a Cull click from the viewport, live mode)."""

    ENVELOPE = "rest"


AT_REST = AtRest.ENVELOPE

REST_LOOK_S = 0.05           # a view unchanged for this long between two looks has stopped moving
MAX_ANGLE_DEG = 30.0         # a wider envelope hides little; a faster turn shows all until it slows


@dataclass(frozen=True)
class LivePolicy:
    """How big an envelope a pass takes and when the displayed set must go."""

    hold_s: float = 0.5          # the envelope lasts this long after the pass lands, at the measured speed
    margin_steps: float = 2.0    # and this many steps of the last motion beyond that
    # the envelope at rest: the first step of a motion must stay inside it (the guard cannot
    # change the redraw it runs before).  0.6 % of the scene and 10 degrees hold an orbit at
    # 90 degrees a second around a pivot a tenth of the scene ahead, at 30 Hz; on the city
    # they hide 3-6 % fewer objects at rest than 0.2 % and 2 degrees (the angle costs ~0)
    rest_rel: float = 0.006      # this share of the scene's size ...
    rest_deg: float = 10.0       # ... and this many degrees

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


class MotionTracker:
    """The view's motion, measured between successive looks at it: the last step
    (eye distance, turn in degrees) and the speeds of the last three looks (the
    fastest counts).  ``now`` is the look's time in seconds (live mode's clock, or
    a replay's)."""

    SPEEDS = 3

    def __init__(self):
        self.view = None
        self.t = None
        self.step = (0.0, 0.0)
        self.speeds = [0.0]
        self.turns = [0.0]

    def observe(self, camera, now):
        """Look at the view: a step when it moved (or held still for a while) since the
        last look with the same lens; another look at the same view soon after is no news."""
        prev, t = self.view, self.t
        if prev is not None and np.array_equal(prev.projection, camera.projection):
            move, turn = view_change(prev, camera)
            if not (move or turn) and now - t < REST_LOOK_S:
                return                                # another redraw of the same view: no news
            dt = max(now - t, 1e-3)
            # a view that held still since the last look has stopped: no step to allow for
            self.step = (move, turn)
            self.speeds = (self.speeds + [move / dt])[-self.SPEEDS:]
            self.turns = (self.turns + [turn / dt])[-self.SPEEDS:]
        self.view, self.t = camera, now

    def envelope(self, policy, latency_s, scene_size):
        """The envelope ``policy`` gives a pass that lands ``latency_s`` from now."""
        return policy.envelope(max(self.speeds), max(self.turns), latency_s, *self.step, scene_size)

    def safe(self, policy, centre, envelope, view):
        """Whether ``view`` and the next step stay inside ``envelope`` around ``centre``."""
        return policy.safe(centre, envelope, view, *self.step)
