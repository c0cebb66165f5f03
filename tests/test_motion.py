"""Live mode's loop (core.motion.LiveLoop) without Blender or GL: when the displayed set
must go, when a pass is due, and whether a pass that lands may be shown."""

import numpy as np

from core.camera import Camera
from core.envelope import Envelope
from core.motion import FIRST_LATENCY_S, MAX_ANGLE_DEG, RETRY_S, LiveLoop, LivePolicy, occluded_share


def walk(x, yaw_deg=0.0, fov=60.0):
    """A camera at (x, 0, 1) looking along +x turned ``yaw_deg`` about z."""
    a = np.radians(yaw_deg)
    return Camera.look_at((x, 0.0, 1.0), (x + np.cos(a), np.sin(a), 1.0), fov_y_deg=fov)


def moving(loop, speed, turn_deg_s=0.0, steps=4, dt=1.0 / 30.0):
    """Look at a view moving at ``speed`` units/s and turning ``turn_deg_s``; the last view."""
    for k in range(steps):
        view = walk(speed * k * dt, turn_deg_s * k * dt)
        loop.look(view, k * dt)
    return view


def test_the_displayed_set_holds_only_inside_its_envelope_with_room_for_the_next_step():
    loop = LiveLoop()
    view = moving(loop, speed=3.0)                              # a step of 0.1 units
    shown = (walk(0.0), Envelope(1.0, 5.0, any_roll=False))
    assert loop.holds(None, view)                               # nothing hidden: nothing to show
    assert loop.holds(shown, view)                              # 0.3 moved + 2 steps of 0.1 <= 1
    assert not loop.holds((walk(-0.6), shown[1]), view)          # 0.9 + 0.2 > 1
    other_lens = (Camera.look_at((0.0, 0.0, 1.0), (1.0, 0.0, 1.0), fov_y_deg=40.0), shown[1])
    assert not loop.holds(other_lens, view)                     # another lens: the envelope says nothing


def test_a_set_made_for_an_unknown_view_holds_for_none_and_wants_a_pass():
    loop = LiveLoop()
    view = moving(loop, speed=0.0)                              # at rest
    unknown = (None, None)                                      # brought back by an undo
    assert not loop.holds(unknown, view)
    assert loop.due(unknown, view)
    exact = (view, Envelope(0.0, 0.0, any_roll=False))          # a pass made for its own view only
    assert loop.holds(exact, view)                              # at rest, at that very view
    assert not loop.holds(exact, walk(0.01))


def test_a_pass_is_due_once_the_displayed_set_would_not_last_until_it_lands():
    loop = LiveLoop()
    view = moving(loop, speed=3.0)
    assert loop.latency() == FIRST_LATENCY_S
    wide = (walk(0.0), Envelope(2.0, 5.0, any_roll=False))      # 0.3 + 3 x 0.1 + 0.2 <= 2: lasts
    narrow = (walk(0.0), Envelope(0.75, 5.0, any_roll=False))   # holds now (0.5), not in 0.1 s (0.8)
    assert loop.holds(narrow, view)
    assert not loop.due(wide, view)
    assert loop.due(narrow, view)
    assert loop.due(None, view)                                  # nothing hidden: a pass may hide
    loop.start(view, 0.1, scene_size=100.0)
    assert not loop.due(None, view)                              # one pass in flight at a time
    loop.drop()
    assert loop.due(None, view)
    # a slower pass: the same set no longer lasts until one started now lands
    loop.latencies = [1.0]
    assert loop.due(wide, view)


def test_a_turn_too_fast_for_any_envelope_starts_no_pass():
    loop = LiveLoop()
    # 120 degrees a second: in 0.3 s of pass the turn alone is 36 degrees, beyond MAX_ANGLE_DEG
    view = moving(loop, speed=0.0, turn_deg_s=120.0)
    loop.latencies = [0.3]
    assert 120.0 * 0.3 > MAX_ANGLE_DEG
    assert not loop.due(None, view)
    loop.latencies = [0.05]                                      # a fast pass can hold that turn
    assert loop.due(None, view)


def test_a_pass_lands_only_where_the_view_stayed_inside_its_envelope():
    loop = LiveLoop()
    view = moving(loop, speed=3.0)
    env = loop.start(view, 1.0, scene_size=100.0)
    assert loop.flight.envelope == env and not env.any_roll
    # the envelope covers the motion over the pass's time and then the hold, at least
    horizon = FIRST_LATENCY_S + max(LivePolicy().hold_passes * FIRST_LATENCY_S, LivePolicy().hold_min_s)
    assert env.distance >= 3.0 * horizon
    assert loop.land((view, env), view, 1.25)                    # nothing moved since the start
    assert loop.flight is None and loop.latencies == [0.25]
    loop.start(view, 2.0, scene_size=100.0)
    far = walk(view.eye[0] + 10 * env.distance)
    assert not loop.land((view, env), far, 2.5)                  # the view left it: not shown
    assert loop.latencies == [0.25, 0.5]
    for t in (0.1, 0.1, 0.1):
        loop.start(view, 3.0, scene_size=100.0)
        loop.land((view, env), view, 3.0 + t)
    assert np.isclose(loop.latency(), 0.1)                       # the slowest of the last three
    loop.start(view, 4.0, envelope=LivePolicy().rest(100.0))
    loop.land((view, env), view, 6.0)
    assert np.isclose(loop.latency(), 0.1)                       # a pass at rest sizes no motion's


def test_a_set_during_motion_lands_only_where_its_saving_pays_for_blenders_update():
    policy = LivePolicy()
    # hold, no update measured: max(1 x 0.2 s, 0.05 s) = 0.2 s
    assert np.isclose(policy.hold_s(0.2), 0.2) and np.isclose(policy.hold_s(0.01), policy.hold_min_s)
    assert policy.worth(0.6, 0.2, None)                          # no update measured yet: it lands
    assert policy.worth(0.6, 0.2, 120.0)                         # 0.2 s x 60 % = 120 ms saved >= its update
    assert not policy.worth(0.6, 0.2, 121.0)
    assert not policy.worth(0.0, 10.0, 0.001)                    # hiding nothing saves nothing
    loop = LiveLoop(policy)
    view = moving(loop, speed=3.0)
    env = loop.start(view, 1.0, scene_size=100.0)
    assert np.isclose(loop.flight.hold, 0.1)                     # nothing known: one pass time
    loop.updated(30.0)                                           # 3,000 objects: 30 ms an update
    assert not loop.land((view, env), view, 1.2, hidden_share=0.1)   # 0.1 s x 10 % < 30 ms
    assert loop.unworthy and not loop.paused and loop.due(None, view)   # another set may pay
    assert loop.share == 0.1
    # the next hold is sized to pay for the update at that share, with slack (a longer hold
    # hides less): 1.5 x 30 ms / 10 % = 0.45 s, and the envelope covers the motion over the
    # pass and that hold
    wider = loop.start(view, 1.3, scene_size=100.0)
    assert np.isclose(loop.flight.hold, policy.pay_slack * 0.3)
    assert wider.distance >= 3.0 * (loop.latency() + loop.flight.hold) > env.distance
    assert loop.land((view, wider), view, 1.5, hidden_share=0.07)   # 0.45 s x 7 % = 31.5 ms: it pays
    assert not loop.unworthy and loop.unpaid == 0
    loop.updated(400.0)                                          # 50,000 objects: 0.4 s an update
    env = loop.start(view, 1.6, scene_size=100.0)
    assert np.isclose(loop.flight.hold, policy.hold_max_s)       # 4 s would pay: the longest hold
    assert not loop.land((view, env), view, 1.8, hidden_share=0.1)   # 1 s x 10 % < 0.4 s
    assert not loop.paused                                       # the hold was sized: one more try
    env = loop.start(view, 1.9, scene_size=100.0)
    assert not loop.land((view, env), view, 2.1, hidden_share=0.1)
    # two sets in a row that did not pay: the next pass waits RETRY_S, then twice as long
    assert not loop.paused and np.isclose(loop.resume_at, 2.1 + RETRY_S)
    loop.tracker.t = 2.1 + 0.9 * RETRY_S
    assert not loop.due(None, view)
    loop.tracker.t = 2.1 + RETRY_S
    assert loop.due(None, view)
    for t in (2.7, 2.9):
        env = loop.start(view, t, scene_size=100.0)
        assert not loop.land((view, env), view, t + 0.1, hidden_share=0.1)
    assert np.isclose(loop.resume_at, 3.0 + 2 * RETRY_S)
    loop.start(view, 3.5, envelope=policy.rest(100.0))          # a rest ends the waits
    assert not loop.paused and loop.unpaid == 0 and loop.resume_at is None and loop.retries == 0
    assert loop.land((view, env), view, 4.0, hidden_share=0.0)   # at rest a set always lands
    loop.updated(1500.0)                                         # an update longer than any hold
    env = loop.start(view, 4.5, scene_size=100.0)
    assert not loop.land((view, env), view, 4.7, hidden_share=0.9)
    assert loop.paused and not loop.due(None, view)              # none can pay: until the next rest
    loop.start(view, 5.0, envelope=policy.rest(100.0))
    loop.land((view, env), view, 5.5)
    loop.updated(30.0)
    env = loop.start(view, 6.0, scene_size=100.0)
    assert loop.land((view, env), view, 6.2, hidden_share=0.9)   # 90 % pays at once
    env = loop.start(view, 7.0, scene_size=100.0)
    assert loop.land((view, env), view, 7.2)                     # no share given: nothing weighed


def test_a_sets_saving_counts_the_triangles_blender_would_draw():
    from core import Visibility
    state = np.array([Visibility.OCCLUDED, Visibility.VISIBLE, Visibility.VIEW_CULLED, Visibility.OCCLUDED])
    tris = np.array([10, 30, 1000, 60])
    assert np.isclose(occluded_share(state, tris), 70 / 100)    # outside the view Blender draws nothing anyway
    assert occluded_share(np.full(2, Visibility.VIEW_CULLED), np.array([5, 5])) == 0.0
