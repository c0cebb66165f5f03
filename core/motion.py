"""Live culling while the view moves: the policy that sizes a pass's envelope and
says when the displayed set must go, and the loop that decides when a pass runs.

A pass hides a set that holds for an envelope around the view it was made from
(:mod:`core.envelope`).  The policy sizes the envelope from the measured motion: the
eye's speed and the turn rate, times the time until the pass lands plus how long it
should last after, plus a margin of a few steps of motion.  Before each redraw the
view is checked against the displayed set's envelope, with room for the next step:
a view about to leave it shows everything first (showing is urgent).  Passes run
beside the interface (live mode's engine thread) and never hold it: while the view
moves, the next pass starts from where the view is once the displayed set would not
last until a pass started now lands; its set is shown when it lands, only if the view
is still inside its envelope (:class:`LiveLoop`).  At rest the envelope is small
(:attr:`LivePolicy.rest_rel`, :attr:`LivePolicy.rest_deg`): the first steps of a new
motion stay in it, and the check before the next redraw catches the rest.

The motion is measured by :class:`MotionTracker`, between successive looks at the
view (live mode's redraws and ticks).  :class:`LiveLoop` is the one copy of those
decisions: live mode (``occ_addon/live.py``) runs it, and so does the benchmark that
replays motions (:mod:`core.lab.motion`, ``python -m core motion SCENE``).
"""

from dataclasses import dataclass
from enum import Enum

import numpy as np

from .camera import view_change
from .cull import Visibility
from .envelope import Envelope


def occluded_share(state, triangles):
    """Of the triangles Blender draws in the view (every object's but those outside it:
    Blender culls those itself), the share of the objects a pass's ``state``
    (:class:`core.Visibility` per object) finds occluded: what hiding them saves of a
    redraw, where the redraw grows with the triangles drawn."""
    state = np.asarray(state)
    triangles = np.asarray(triangles, dtype=np.int64)
    drawn = int(triangles[state != Visibility.VIEW_CULLED].sum())
    return float(triangles[state == Visibility.OCCLUDED].sum()) / drawn if drawn else 0.0


class AtRest(Enum):
    """An envelope named before its scene is known: :meth:`LivePolicy.rest` sizes it from
    the engine's scene once that is built (a Cull click from the viewport, live mode)."""

    ENVELOPE = "rest"


AT_REST = AtRest.ENVELOPE

REST_LOOK_S = 0.05           # a view unchanged for this long between two looks has stopped moving
MAX_ANGLE_DEG = 30.0         # a wider envelope hides little; a faster turn shows all until it slows
FIRST_LATENCY_S = 0.1        # a pass's time before any was measured
UNPAID_RUN = 2               # sets in a row during a motion that do not pay: the next pass waits ...
RETRY_S = 0.5                # ... this long, twice as long after each such run, up to ...
RETRY_MAX_S = 4.0            # ... this (the motion may slow down; each pass costs its reads)


@dataclass(frozen=True)
class LivePolicy:
    """How big an envelope a pass takes and when the displayed set must go."""

    # the envelope lasts this many pass times after the pass lands, at the measured speed
    # (the next pass starts once the displayed set would not outlast one: it lands in time)
    hold_passes: float = 1.0
    hold_min_s: float = 0.05     # and at least this long (a redraw and a half at 30 Hz)
    # and, once Blender's update is measured, long enough for the set's saving to pay for it
    # (the last pass's share hidden), up to this long: a longer one covers so much motion that
    # it hides little (at the city's drag speed, a second is a fifth of the scene)
    hold_max_s: float = 1.0
    # a hold sized from the last share is sized for this many times the update: a longer
    # hold is a wider envelope, whose set hides less (the city at 30 ms an update: 45 % of
    # the triangles with a 0.05 s hold, 40 % with 0.07 s; with a factor of 1 two sets in a row
    # fell just short and ended the motion's passes)
    pay_slack: float = 1.5
    margin_steps: float = 2.0    # and this many steps of the last motion beyond that
    # the envelope at rest: the first step of a motion must stay inside it (the guard cannot
    # change the redraw it runs before).  0.6 % of the scene and 10 degrees hold an orbit at
    # 90 degrees a second around a pivot a tenth of the scene ahead, at 30 Hz; on the city
    # they hide 3-6 % fewer objects at rest than 0.2 % and 2 degrees (the angle costs ~0)
    rest_rel: float = 0.006      # this share of the scene's size ...
    rest_deg: float = 10.0       # ... and this many degrees

    def envelope(self, speed, turn_deg_s, latency_s, step_move, step_turn_deg, scene_size, hold_s=None):
        """The envelope of a pass that lands ``latency_s`` from now and is shown for
        ``hold_s`` after (None: :meth:`hold_s`'s least), the view moving at ``speed``
        (scene units per second) and turning ``turn_deg_s``."""
        horizon = latency_s + (self.hold_s(latency_s) if hold_s is None else hold_s)
        d = max(speed * horizon + self.margin_steps * step_move, self.rest_rel * scene_size)
        a = max(turn_deg_s * horizon + self.margin_steps * step_turn_deg, self.rest_deg)
        # the turn measured is the frame's (roll included): a narrower view than any roll;
        # every view is checked against the pass's envelope: it may keep its eyes above a floor
        return Envelope(d, min(a, MAX_ANGLE_DEG), any_roll=False, above_floor=True)

    def hold_s(self, latency_s, share=None, update_ms=None):
        """How long a set made during motion is shown before the next one replaces it (or
        the view leaves it): the hold after landing that :meth:`envelope` sizes.  At least
        a pass's time (the next set lands about then) and :attr:`hold_min_s`; with
        Blender's update measured (``update_ms``) and the share of the triangles in the
        view the last pass hid (``share``), long enough for a set hiding as much to pay
        for :attr:`pay_slack` times its update (:meth:`worth`), up to :attr:`hold_max_s`.
        A longer hold is a wider envelope, which hides less: the next pass's share sizes
        the next hold."""
        hold = max(self.hold_passes * latency_s, self.hold_min_s)
        if update_ms is not None and share is not None and share > 0.0:
            hold = max(hold, min(self.pay_slack * update_ms / (1e3 * share), self.hold_max_s))
        return hold

    def worth(self, hidden_share, hold_s, update_ms):
        """Whether a set made during motion pays for Blender's update: while the user
        navigates the view redraws back to back, so a set hiding ``hidden_share`` of the
        triangles in the view saves about that share of the redraw time it is shown for
        (``hold_s``, what its envelope was sized for: the next set replaces it about
        then), and costs its own update (``update_ms``, the last measured; None: none yet,
        it lands), which holds Blender's main thread.  A set that saves less than that is
        not shown: the redraws meanwhile draw what they drew, and the main thread keeps
        the time."""
        if update_ms is None:
            return True
        return 1e3 * hold_s * hidden_share >= update_ms

    def reachable(self, turn_deg_s, latency_s, step_turn_deg):
        """Whether a pass that lands ``latency_s`` from now can hold when it lands: the turn
        until then, and the next step, within :data:`MAX_ANGLE_DEG` (a faster turn shows
        everything until it slows; a pass started then would only be dropped)."""
        return turn_deg_s * latency_s + self.margin_steps * step_turn_deg <= MAX_ANGLE_DEG

    def rest(self, scene_size):
        """The envelope of a pass made at rest: what the first steps of a motion need
        before the check before each redraw sees them."""
        return Envelope(self.rest_rel * scene_size, self.rest_deg, any_roll=False, above_floor=True)

    def safe(self, centre, envelope, view, step_move, step_turn_deg, step_eye=None):
        """Whether ``view`` and the next step (as large as ``margin_steps`` of the last;
        towards a floor, as far as ``margin_steps`` of the last one's way down) stay inside
        ``envelope`` around ``centre``."""
        return self.lasts(centre, envelope, view, 0.0, 0.0, 0.0, step_move, step_turn_deg, step_eye=step_eye)

    def lasts(self, centre, envelope, view, seconds, speed, turn_deg_s, step_move, step_turn_deg,
              velocities=None, step_eye=None):
        """Whether ``view``, moving on at ``speed`` and ``turn_deg_s`` for ``seconds``, and
        then the next step, stays inside ``envelope`` around ``centre``.  Above the
        envelope's floor the eye sinks as measured: at the fastest of ``velocities`` (the
        last looks' ``(3,)`` eye velocities), then the next step as the last one
        (``step_eye``, ``(3,)``); without them, at ``speed`` and a step any way."""
        if not np.array_equal(centre.projection, view.projection):
            return False                                          # another lens: the envelope says nothing
        move, turn = view_change(centre, view, frame=not envelope.any_roll)
        step = self.margin_steps * step_move
        if move + speed * seconds + step > envelope.distance \
                or turn + turn_deg_s * seconds + self.margin_steps * step_turn_deg > envelope.angle_deg:
            return False
        if envelope.floor is None:
            return True
        up = np.asarray(envelope.floor[:3])
        sink = speed if velocities is None else max(0.0, *(-float(np.dot(v, up)) for v in velocities))
        if step_eye is not None:
            step = self.margin_steps * max(0.0, -float(np.dot(step_eye, up)))
        return envelope.height(view.eye) >= sink * seconds + step


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
        self.velocities = [np.zeros(3)]     # the eye's, the last looks' (which way it goes)
        self.step_eye = np.zeros(3)         # the last step's eye move

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
            self.step_eye = camera.eye - prev.eye
            self.velocities = (self.velocities + [self.step_eye / dt])[-self.SPEEDS:]
            self.turns = (self.turns + [turn / dt])[-self.SPEEDS:]
        self.view, self.t = camera, now

    def envelope(self, policy, latency_s, scene_size, hold_s=None):
        """The envelope ``policy`` gives a pass that lands ``latency_s`` from now and is
        shown for ``hold_s`` after."""
        return policy.envelope(max(self.speeds), max(self.turns), latency_s, *self.step, scene_size, hold_s)

    def safe(self, policy, centre, envelope, view):
        """Whether ``view`` and the next step stay inside ``envelope`` around ``centre``."""
        return policy.safe(centre, envelope, view, *self.step, step_eye=self.step_eye)

    def lasts(self, policy, centre, envelope, view, seconds):
        """Whether the view, moving on as measured for ``seconds``, then the next step,
        stays inside ``envelope`` around ``centre``."""
        return policy.lasts(centre, envelope, view, seconds, max(self.speeds), max(self.turns), *self.step,
                            velocities=self.velocities, step_eye=self.step_eye)


@dataclass(frozen=True)
class Flight:
    """A pass in flight: the view it is made from, its envelope (or :data:`AT_REST`) and
    when it started (the loop's clock)."""

    view: object
    envelope: object
    started: float
    rest: bool = False          # made with a given envelope (at rest): its time sizes no motion's
    hold: float = 0.0           # how long its set is to be shown after it lands (during motion)


class LiveLoop:
    """Live mode's decisions while the view moves, without Blender (live mode and the
    motion benchmark both run them):

    - :meth:`look` at the view at every redraw and tick (the motion is measured);
    - :meth:`holds`: whether the displayed set (``shown``: the camera and envelope it
      was made for, or None when nothing is hidden; a camera of None: made for a view
      nobody knows, it holds for none) holds for the view and its next step; when
      not, everything is shown before the next redraw;
    - :meth:`due`: while the view moves, whether a pass should start now: none is in
      flight, the displayed set would not last until a pass started now lands, and the
      turn until then leaves such a pass a chance to hold (:meth:`LivePolicy.reachable`);
      :meth:`start` sizes its envelope (the measured motion over the pass's time);
    - :meth:`land`: the pass in flight finished; its set is shown only if the view is
      still inside its envelope (with room for the next step) and, during motion, its
      saving pays for Blender's update (:meth:`LivePolicy.worth`; the update measured
      after each set that changed something, :meth:`updated`).  A set is held long
      enough to pay, as far as the last pass's share says (:meth:`hold`); where
      :data:`UNPAID_RUN` sets in a row did not pay, the next pass waits
      (:data:`RETRY_S`, doubling up to :data:`RETRY_MAX_S`), and where none could (the
      update outlasts the longest hold), the passes of this motion end: the next starts
      at rest.  A
      pass's time during motion (start to landing, the slowest of the last few) sizes
      the next envelope; a pass at rest is other work (a small envelope, the image
      probed: the city-xl's took 0.9 s on llvmpipe where its passes during motion took
      35 ms) and sizes none.
    """

    LATENCIES = 3

    def __init__(self, policy=None):
        self.policy = policy or LivePolicy()
        self.tracker = MotionTracker()
        self.flight: Flight | None = None
        self.latencies: list[float] = []
        self.update_ms: float | None = None      # Blender's update after the last set that changed something
        self.paused = False                      # no set during this motion can pay for its update
        self.unworthy = False                    # the last set to land during motion did not pay for it
        self.share: float | None = None          # of the triangles in the view, the share the last pass hid
        self.unpaid = 0                          # sets in a row during this motion that did not pay
        self.retries = 0                         # runs of unpaid sets during this motion
        self.resume_at: float | None = None      # no pass during motion starts before this (the loop's clock)

    def updated(self, blender_ms):
        """A set was shown that changed what is hidden; Blender's update took ``blender_ms``."""
        self.update_ms = float(blender_ms)

    def look(self, view, now):
        self.tracker.observe(view, now)

    def holds(self, shown, view):
        if shown is None:
            return True                               # nothing hidden holds anywhere
        return shown[0] is not None and self.tracker.safe(self.policy, shown[0], shown[1], view)

    def latency(self):
        """The time a pass started now will take to land: the slowest of the last few."""
        return max(self.latencies) if self.latencies else FIRST_LATENCY_S

    def due(self, shown, view):
        t = self.tracker
        if self.flight is not None or self.paused or not self.policy.reachable(max(t.turns), self.latency(), t.step[1]):
            return False
        if self.resume_at is not None and t.t is not None and t.t < self.resume_at:
            return False
        return shown is None or shown[0] is None or not t.lasts(self.policy, shown[0], shown[1], view,
                                                                  self.latency())

    def hold(self):
        """How long a set made by a pass started now is to be shown after it lands
        (:meth:`LivePolicy.hold_s`: long enough to pay for Blender's update)."""
        return self.policy.hold_s(self.latency(), self.share, self.update_ms)

    def start(self, view, now, scene_size=None, envelope=None):
        """A pass starts from ``view``: its envelope, the measured motion's over the pass's
        time and its hold (``envelope`` given, e.g. :data:`AT_REST`: that one)."""
        rest = envelope is not None
        if rest:
            self.paused = False
            self.unpaid = self.retries = 0
            self.resume_at = None
        hold = self.hold()
        if envelope is None:
            envelope = self.tracker.envelope(self.policy, self.latency(), scene_size, hold)
        self.flight = Flight(view, envelope, now, rest, hold)
        return envelope

    def land(self, shown, view, now, hidden_share=None):
        """The pass in flight finished at ``now``; ``shown``: the camera and envelope its set
        holds for; ``hidden_share``: of the triangles in the view (what Blender draws), the
        share its set hides (None: not known, no saving weighed).  Whether its set may be
        shown for ``view``."""
        flight, self.flight = self.flight, None
        rest = flight.rest
        if not rest:
            self.latencies = (self.latencies + [max(now - flight.started, 0.0)])[-self.LATENCIES:]
        if hidden_share is not None:
            self.share = hidden_share             # what the next pass may hide: it sizes the next hold
        self.unworthy = (not rest and hidden_share is not None
                         and not self.policy.worth(hidden_share, flight.hold, self.update_ms))
        if self.unworthy:
            # the next hold is sized from this share.  Where that did not pay either, passes
            # during this motion only cost the main thread their reads: the next waits
            # (RETRY_S, doubling); where not even a set hiding everything, held as long as
            # any, would pay, none starts until the next rest
            self.unpaid += 1
            self.paused = not self.policy.worth(1.0, self.policy.hold_max_s, self.update_ms)
            if self.unpaid >= UNPAID_RUN:
                self.resume_at = now + min(RETRY_S * 2.0 ** self.retries, RETRY_MAX_S)
                self.retries += 1
                self.unpaid = 0
            return False
        if not rest and hidden_share is not None:
            self.unpaid = self.retries = 0
        return self.holds(shown, view)

    def drop(self):
        """The pass in flight is void (the scene changed under it): nothing lands."""
        self.flight = None
