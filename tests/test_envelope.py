"""The motion envelope: what a pass hides stays hidden from every view of the envelope."""

import math
from dataclasses import replace

import numpy as np
import pytest

from core import Camera, Culler, OccError, Scene, Visibility
from core.bounds import corners
from core.camera import look_at
from core.envelope import Envelope, corner_half_angle, envelope_camera, sample_views
from core.umbra import convex_polygons, hidden_by_polygons
from tests import scenes


def _window_wall_scene():
    """A wall at x = 10 with a 2 x 2 window, a small plate at x = 3 that covers the
    window from the origin, and a panel behind the window (hidden from the origin,
    seen through the window once the eye steps aside)."""
    boxes = [((10, -20, -20), (10.2, -1, 20)), ((10, 1, -20), (10.2, 20, 20)),
             ((10, -1, -20), (10.2, 1, -1)), ((10, -1, 1), (10.2, 1, 20)),
             ((3, -0.45, -0.45), (3.05, 0.45, 0.45)), ((14, -1.5, -1.5), (14.3, 1.5, 1.5))]
    scene = scenes.boxes_scene(boxes, ["wall_a", "wall_b", "wall_c", "wall_d", "plate", "panel"])
    camera = scenes.cam((0, 0, 0), (1, 0, 0), near=0.1, far=100, fov_y_deg=50, aspect=1.0)
    return scene, camera


def _seen_from(culler, views):
    seen = np.zeros(len(culler), dtype=bool)
    for v in views:
        seen |= culler.truth(v)
    return seen


@pytest.mark.parametrize("distance, hidden", [(0.05, True), (0.3, False), (1.0, False)])
def test_plate_before_a_window_hides_only_while_the_window_stays_covered(ctx, distance, hidden):
    scene, camera = _window_wall_scene()
    with Culler(scene, resolution=(128, 128), ctx=ctx) as c:
        assert c.cull(camera, fresh=True).state[5] == Visibility.OCCLUDED     # the point pass hides it
        result = c.cull(camera, envelope=(distance, 0.0))
        views = sample_views(camera, Envelope(distance, 0.0), 120, np.random.default_rng(1))
        seen = _seen_from(c, views)
    assert (result.state[5] != Visibility.VISIBLE) == hidden
    assert seen[5] == (not hidden)              # the case is real: a view of the envelope sees it
    assert not (seen & ~result.visible).any()


def test_a_wall_hides_from_every_eye_of_the_ball(ctx):
    scene = scenes.boxes_scene([((5, -30, -30), (5.5, 30, 30)), ((9, -1, -1), (10, 1, 1))], ["wall", "crate"])
    camera = scenes.cam((0, 0, 0), (1, 0, 0), near=0.1, far=100, fov_y_deg=60, aspect=1.5)
    with Culler(scene, resolution=(96, 64), ctx=ctx) as c:
        result = c.cull(camera, envelope=(2.0, 10.0))
    assert result.state.tolist() == [Visibility.VISIBLE, Visibility.OCCLUDED]


def test_eye_beyond_a_near_wall_sees_behind_it(ctx):
    """A wall closer than D: an eye of the ball stands behind it, so nothing is hidden."""
    scene = scenes.boxes_scene([((1, -30, -30), (1.1, 30, 30)), ((9, -1, -1), (10, 1, 1))], ["wall", "crate"])
    camera = scenes.cam((0, 0, 0), (1, 0, 0), near=0.05, far=100, fov_y_deg=60, aspect=1.5)
    with Culler(scene, resolution=(96, 64), ctx=ctx) as c:
        assert c.cull(camera, fresh=True).state[1] == Visibility.OCCLUDED
        assert c.cull(camera, envelope=(1.5, 0.0)).state[1] == Visibility.VISIBLE


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_random_cities_hide_nothing_any_view_of_the_envelope_sees(ctx, seed):
    scene, cams, _ = scenes.random_city(seed, 300)
    rng = np.random.default_rng(seed)
    hidden_total = 0
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        for camera in cams:
            for env in (Envelope(0.5, 5.0), Envelope(2.0, 10.0)):
                result = c.cull(camera, envelope=env)
                seen = _seen_from(c, sample_views(camera, env, 12, rng))
                assert not (seen & ~result.visible).any(), (seed, env)
                hidden_total += int((~result.visible).sum())
    assert hidden_total > 0                      # the envelope hides something: the check can fail


def test_a_turn_beyond_the_lens_view_culls_nothing_it_may_see(ctx):
    scene, cams, _ = scenes.random_city(5, 200)
    camera = cams[0]
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        result = c.cull(camera, envelope=(0.0, 20.0))
        views = sample_views(camera, Envelope(0.0, 20.0), 30, np.random.default_rng(5))
        seen = _seen_from(c, views)
    assert not (seen & (result.state == Visibility.VIEW_CULLED)).any()


def test_zero_envelope_hides_nothing_the_truth_sees(ctx):
    scene, cams, _ = scenes.random_city(7, 200)
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        for camera in cams:
            truth = c.truth(camera)
            env = c.cull(camera, envelope=(0.0, 0.0))
            assert not (truth & ~env.visible).any()
            assert (~env.visible).sum() > 0


def test_orthographic_views_hide_no_occluded_object(ctx):
    scene, cams, _ = scenes.slit_wall(3)
    with Culler(scene, resolution=scenes.SLIT_RESOLUTION, ctx=ctx) as c:
        assert c.cull(cams[0], fresh=True).state[3] == Visibility.OCCLUDED
        assert (c.cull(cams[0], envelope=(0.1, 0.0)).state != Visibility.OCCLUDED).all()
        assert (c.cull(cams[0], envelope=(0.1, 1.0)).state == Visibility.VISIBLE).all()


def test_square_view_holds_the_lens_turned_any_way():
    camera = Camera.look_at((0, 0, 0), (0, 1, 0), fov_y_deg=60, aspect=16 / 9)
    half = corner_half_angle(camera)
    assert half == pytest.approx(math.atan(math.tan(math.radians(30)) * math.hypot(1, 16 / 9)))
    view = envelope_camera(camera, Envelope(0, 10), 360)
    assert view.cull.projection[1, 1] == pytest.approx(1 / math.tan(half + math.radians(10)))
    assert view.cull.projection[0, 0] == pytest.approx(view.cull.projection[1, 1])      # a square
    inner = view.hi[1] - view.lo[1] + 1
    assert inner >= 360 and view.lo[1] >= 4 and view.size[1] == inner + 2 * view.lo[1]
    # the render frustum's pixels at the cull frustum's edge are the cull frustum's edge
    assert view.render.projection[1, 1] * view.size[1] == pytest.approx(view.cull.projection[1, 1] * inner)
    assert envelope_camera(camera, Envelope(0, 40), 360) is None      # wider than 80 degrees


def test_a_frame_turn_needs_less_than_any_roll():
    camera = Camera.look_at((0, 0, 0), (0, 1, 0), fov_y_deg=60, aspect=16 / 9)
    rolled = envelope_camera(camera, Envelope(0, 5), 360)
    framed = envelope_camera(camera, Envelope(0, 5, any_roll=False), 360)
    assert framed.size[0] * framed.size[1] < 0.6 * rolled.size[0] * rolled.size[1]
    # the lens's own half-angles plus at least the turn, on both axes
    assert 1 / framed.cull.projection[1, 1] >= math.tan(math.radians(35))
    assert 1 / framed.cull.projection[0, 0] >= math.tan(math.atan(16 / 9 * math.tan(math.radians(30)))
                                                         + math.radians(5))


@pytest.mark.parametrize("seed", [0, 1])
def test_frame_turns_hide_nothing_a_turned_view_sees(ctx, seed):
    scene, cams, _ = scenes.random_city(seed + 20, 300)
    rng = np.random.default_rng(seed)
    hidden = 0
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        for camera in cams:
            env = Envelope(0.5, 6.0, any_roll=False)
            result = c.cull(camera, envelope=env)
            seen = _seen_from(c, sample_views(camera, env, 20, rng))
            assert not (seen & ~result.visible).any()
            hidden += int((~result.visible).sum())
    assert hidden > 0


@pytest.mark.parametrize("text", ["2", "a,b", "-1,10", "1,90", "nan,1", "1,2,3"])
def test_bad_envelopes_get_one_clear_error(text):
    with pytest.raises(OccError, match="envelope"):
        Envelope.parse(text)


def test_a_box_mesh_gives_its_six_faces():
    polys, areas = convex_polygons(scenes.UNIT_BOX_V, scenes.UNIT_BOX_F)
    assert len(polys) == 6
    np.testing.assert_allclose(areas, 1.0)


def test_a_rebuilt_scene_proves_with_its_own_meshes_polygons(ctx):
    """The engine rebuilt for scenes whose wall mesh alternates between a wall that hides
    the crate and a post that does not, each made of fresh arrays (as the add-on makes
    them after an edit): every envelope pass proves with the current mesh's polygons.
    Python reuses a freed array's id, and a memo keyed by ids that outlived its scene
    lent the old wall's faces to the new post (workflow seed 7380: a cube hidden behind
    its own old, larger faces)."""
    camera = scenes.cam((0, 0, 0), (1, 0, 0), near=0.1, far=100, fov_y_deg=60, aspect=1.5)
    faces = np.array(scenes.UNIT_BOX_F)                  # unchanged faces: the same array each time
    crate = (np.array(scenes.UNIT_BOX_V), faces)

    def scene(half):
        wall = (np.array(scenes.UNIT_BOX_V, dtype=np.float64) - 0.5) * (0.5, 2 * half, 2 * half) + (5.25, 0, 0)
        return Scene.from_arrays(["wall", "crate"], [(wall, faces), crate], np.array([0, 1]),
                                 np.array([np.eye(4), scenes.box_matrix((9, -1, -1), (10, 1, 1))]))

    walls = np.random.default_rng(5).random(24) < 0.5
    with Culler(scene(30.0), resolution=(96, 64), ctx=ctx) as c:
        for k, wide in enumerate(walls.tolist()):
            if k or not wide:
                c.replace_scene(scene(30.0 if wide else 0.2))
            assert c.truth(camera)[1] != wide                           # the premise
            state = c.cull(camera, envelope=(1.0, 5.0)).state[1]
            assert state == (Visibility.OCCLUDED if wide else Visibility.VISIBLE), k


def test_a_square_hides_what_its_umbra_holds():
    square = np.array([[[-2, -2, -10], [2, -2, -10], [2, 2, -10], [-2, 2, -10]]], dtype=float)
    box = np.array([[[-0.5, -0.5, -14], [0.5, 0.5, -13]]])
    assert hidden_by_polygons(box, square, 0.5).tolist() == [True]
    # the plane through the square's edge x = 2 and the corner (0.5, y, -14) passes
    # 23 / sqrt(18.25) = 5.384 from the eye: a ball of radius 5.3 stays on the
    # square's side, one of 5.5 holds an eye that looks past the edge at that corner
    assert hidden_by_polygons(box, square, 5.3).tolist() == [True]
    assert hidden_by_polygons(box, square, 5.5).tolist() == [False]
    # a ball that reaches the square's plane can stand behind it
    assert hidden_by_polygons(box, square, 10.5).tolist() == [False]


def test_a_box_within_the_depth_buffers_rounding_behind_a_square_is_not_hidden():
    """The square hides a box 0.1 behind its plane from the ball; a depth buffer that
    rounds by more than that draws the box through the square, so with that guard it
    stays visible (fuzz seed 174: a box 0.1 behind a wall at 314, 0.7 a depth step)."""
    square = np.array([[[-2, -2, -10], [2, -2, -10], [2, 2, -10], [-2, 2, -10]]], dtype=float)
    box = np.array([[[-0.5, -0.5, -11], [0.5, 0.5, -10.1]]])
    assert hidden_by_polygons(box, square, 0.5).tolist() == [True]
    assert hidden_by_polygons(box, square, 0.5, depth_guard=np.array([0.05])).tolist() == [True]
    assert hidden_by_polygons(box, square, 0.5, depth_guard=np.array([0.2])).tolist() == [False]


def _edge_plane_slack(box, poly, radius):
    """The module doc's condition (2), corner by corner, edge by edge (the reference): the
    least distance from the eye to the plane through a corner of ``box`` and an edge of
    ``poly``, signed by the ball's side (positive: the polygon's side), less ``radius``."""
    centre = poly.mean(axis=0)
    least = np.inf
    for x in corners(box[None])[0]:
        for e in range(4):
            a0, a1 = poly[e], poly[(e + 1) % 4]
            if np.array_equal(a0, a1):
                continue
            m = np.cross(a1 - a0, x - a0)
            side = m @ (centre - a0)
            d = (-m @ a0) / np.linalg.norm(m) if side > 0 else (m @ a0) / np.linalg.norm(m)
            least = min(least, d - radius)
    return least


def _random_polygons(rng, k):
    """Convex quads and triangles (a repeated corner) 3-30 from the eye, facing it roughly."""
    polys = []
    for _ in range(k):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        centre = normal * rng.uniform(3, 30)
        a = np.cross(normal, rng.normal(size=3))
        a /= np.linalg.norm(a)
        b = np.cross(normal, a)
        angles = np.sort(rng.uniform(0, 2 * np.pi, 4))
        corners = [centre + rng.uniform(1, 8) * (np.cos(t) * a + np.sin(t) * b) for t in angles]
        if rng.random() < 0.3:
            corners[3] = corners[2]
        polys.append(corners)
    return np.array(polys)


@pytest.mark.parametrize("seed", range(4))
def test_the_tangent_planes_prove_what_the_edge_planes_prove(seed):
    """The umbra as five half-spaces (one matrix product) against the module doc's
    condition checked corner by corner and edge by edge: the same answer wherever the
    reference is not within a rounding guard of its boundary, and both ways occur."""
    rng = np.random.default_rng(seed)
    polys = _random_polygons(rng, 12)
    centres = polys.mean(axis=1)[rng.integers(0, 12, 200)] * rng.uniform(1.05, 2.5, (200, 1))
    half = rng.uniform(0.05, 2.0, (200, 1, 3))
    boxes = np.concatenate([centres[:, None] - half, centres[:, None] + half], axis=1)
    distance = float(rng.uniform(0.0, 2.5))
    got = hidden_by_polygons(boxes, polys, distance)
    hidden = shown = 0
    for i, box in enumerate(boxes):
        for p, poly in enumerate(polys):
            n = np.cross(poly[1] - poly[0], poly[2] - poly[0])
            n /= np.linalg.norm(n) * np.sign(n @ poly[0])
            h = n @ poly[0]
            beyond = box[0] @ np.maximum(n, 0) + box[1] @ np.minimum(n, 0) > h     # its nearest corner
            if not beyond or h <= distance:
                continue
            slack = _edge_plane_slack(box, poly, distance)
            if abs(slack) < 1e-4 * (1 + np.abs(box).max()):
                continue                                   # inside the guards: either answer
            mine = hidden_by_polygons(box[None], poly[None], distance)[0]
            assert mine == (slack > 0), (seed, i, p, slack)
            hidden += bool(mine)
            shown += not mine
    assert hidden > 5 and shown > 5
    assert got.any()


def _boxes_behind(rng, polys, count=300):
    """Boxes beyond the polygons (around their centres, pushed 5-100 % farther out)."""
    centres = polys.mean(axis=1)[rng.integers(0, len(polys), count)] * rng.uniform(1.05, 2.0, (count, 1))
    half = rng.uniform(0.05, 1.5, (count, 1, 3))
    return np.concatenate([centres[:, None] - half, centres[:, None] + half], axis=1)


def _every_segment_crosses(poly, eyes, points):
    """Whether every segment from one of ``eyes`` to one of ``points`` meets the convex
    polygon ``poly`` ``(4, 3)`` (a triangle repeating a corner) strictly between its ends."""
    n = np.cross(poly[1] - poly[0], poly[2] - poly[0])
    b, x = eyes[:, None], points[None]                     # every eye against every point
    t = ((poly[0] - b) @ n) / ((x - b) @ n)
    if not ((t > 0.0) & (t < 1.0)).all():                  # the segment meets the polygon's plane ...
        return False
    q = b + t[..., None] * (x - b)
    for e in range(4):                                     # ... inside the polygon
        a0, a1 = poly[e], poly[(e + 1) % 4]
        if not np.array_equal(a0, a1) and not (np.cross(a1 - a0, q - a0) @ np.cross(a1 - a0, poly.mean(axis=0) - a0)
                                               >= 0.0).all():
            return False
    return True


def _cap_eyes(rng, distance, cut, count):
    """Eyes of the ball cut by ``f . x >= s``: inside it, on its sphere and on its rim."""
    f, s = cut
    out = []
    while len(out) < count:
        e = rng.normal(size=3)
        e *= distance * (rng.random() ** (1 / 3) if len(out) % 3 else 1.0) / np.linalg.norm(e)
        if len(out) % 5 == 4:                              # on the rim: the cut plane meets the sphere
            t = np.cross(f, e)
            t *= np.sqrt(max(distance ** 2 - s ** 2, 0.0)) / max(np.linalg.norm(t), 1e-12)
            e = s * f + t
        if f @ e >= s:
            out.append(e)
    return np.array(out)


@pytest.mark.parametrize("seed", range(4))
def test_a_cut_ball_hides_what_the_ball_hides_and_no_ray_from_its_eyes_reaches_it(seed):
    """Eyes kept above a floor (``cut``): everything the whole ball's polygons hide is
    still hidden, and for every box hidden, segments from eyes of the cut ball
    (inside, on the sphere, on the rim) to points of the box all cross a polygon that
    hides it (the same independent check as the ball's, below)."""
    rng = np.random.default_rng(300 + seed)
    polys = _random_polygons(rng, 16)
    boxes = _boxes_behind(rng, polys)
    distance = float(rng.uniform(0.5, 2.5))
    f = rng.normal(size=3)
    f /= np.linalg.norm(f)
    cut = (f, -float(rng.uniform(0.05, 0.9)) * distance)
    ball = hidden_by_polygons(boxes, polys, distance)
    capped = hidden_by_polygons(boxes, polys, distance, cut=cut)
    assert not (ball & ~capped).any()
    checked = 0
    for i in np.flatnonzero(capped):
        by = [p for p in range(len(polys))
              if hidden_by_polygons(boxes[i:i + 1], polys[p:p + 1], distance, cut=cut)[0]]
        poly = polys[by[0]]
        pts = rng.uniform(boxes[i, 0], boxes[i, 1], (40, 3))
        pts[:8] = corners(boxes[i:i + 1])[0]
        assert _every_segment_crosses(poly, _cap_eyes(rng, distance, cut, 40), pts), (seed, i)
        checked += 1
    assert checked > 3


def test_a_facade_hides_a_box_on_the_ground_only_from_eyes_kept_above_it():
    """A facade standing on the ground 10 ahead, a box on the ground behind it, eyes 1.7
    above the ground within 2: an eye of the ball below the ground sees the box under
    the facade's lower edge (no proof), eyes kept 0.5 above the ground do not."""
    facade = np.array([[[10, -5, -1.7], [10, 5, -1.7], [10, 5, 1.5], [10, -5, 1.5]]], float)
    box = np.array([[[14, -1, -1.7], [15, 1, -1.0]]], float)
    up = np.array([0.0, 0.0, 1.0])
    assert not hidden_by_polygons(box, facade, 2.0)[0]
    assert hidden_by_polygons(box, facade, 2.0, cut=(up, -1.2))[0]
    assert not hidden_by_polygons(box, facade, 2.0, cut=(up, -1.9))[0]      # eyes below the ground again
    assert not hidden_by_polygons(box, facade, 2.0, cut=(-up, -1.2))[0]     # a ceiling: the low eyes stay


@pytest.mark.parametrize("seed", range(3))
def test_what_the_polygons_hide_no_ray_from_the_ball_reaches(seed):
    """Independent of both formulas: for every box the proof hides, segments from points of
    the ball of eyes (on its surface and inside) to points of the box (corners, faces,
    inside) all cross one of the polygons that hide it."""
    rng = np.random.default_rng(100 + seed)
    polys = _random_polygons(rng, 16)
    boxes = _boxes_behind(rng, polys)
    distance = float(rng.uniform(0.2, 2.0))
    checked = 0
    for i in np.flatnonzero(hidden_by_polygons(boxes, polys, distance)):
        by = [p for p in range(len(polys)) if hidden_by_polygons(boxes[i:i + 1], polys[p:p + 1], distance)[0]]
        poly = polys[by[0]]
        eyes = rng.normal(size=(64, 3))
        eyes *= (distance * rng.uniform(0.5, 1.0, (64, 1)) ** (1 / 3)) / np.linalg.norm(eyes, axis=1)[:, None]
        eyes[:16] *= distance / np.linalg.norm(eyes[:16], axis=1)[:, None]      # on the sphere
        pts = rng.uniform(boxes[i, 0], boxes[i, 1], (64, 3))
        pts[:8] = corners(boxes[i:i + 1])[0]
        assert _every_segment_crosses(poly, eyes, pts), (seed, i)
        checked += 1
    assert checked > 3


def test_motion_replays_hide_nothing_the_truth_sees(ctx):
    """Live mode's policy replayed with passes that land when they finish: inside its
    envelope a set hides nothing the truth sees, and the one step drawn outside one is
    a motion's first from rest (the lab's drag starts fast: README Limits)."""
    from core.lab.motion import MOTIONS, motions, replay
    scene, cams, _ = scenes.random_city(4, 250)
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        hidden = 0
        for name in MOTIONS:
            rows, passes = replay(c, motions(cams[:2], c.scene_size, name)[:45])
            assert sum(r["false_negatives"] for r in rows if not r["late"]) == 0, name
            assert not [r["step"] for r in rows[2:] if r["late"]], name
            assert passes and rows[0]["step"] == 0
            hidden += sum(r["hidden"] for r in rows)
            assert all(0 <= r["held"] <= r["ideal"] and r["triangles"] <= r["triangles_vfc"] for r in rows)
    assert hidden > 0


def test_a_first_step_beyond_the_rest_envelope_is_drawn_late(ctx):
    """The guard runs before a redraw but cannot change what it draws: a motion whose first
    step from rest leaves the rest envelope draws that step with the rest pass's set, and
    the replay says so (and counts what it hides that the truth sees)."""
    from core.lab.motion import replay
    scene, cams, _ = scenes.random_city(4, 250)
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        a = cams[0]
        jump = Camera(look_at(a.eye + 0.05 * c.scene_size * a.direction, a.eye + 2 * a.direction, [0, 0, 1]),
                      a.projection)
        rows, _ = replay(c, [a, jump] + [jump] * 30)
    assert [r["late"] for r in rows[:2]] == [False, True]
    assert len(rows) > 2 and not any(r["late"] for r in rows[2:])    # the pass during motion landed


def test_a_wall_the_near_plane_cuts_hides_nothing(ctx):
    """A wall 0.2 from the eye with the near plane at 0.5: every eye of the envelope clips
    it away, so what stands behind it is seen (workflow seed 3210: a camera nudged into
    a wall's thickness)."""
    scene = scenes.boxes_scene([((0.2, -30, -30), (0.3, 30, 30)), ((5, -1, -1), (6, 1, 1))], ["wall", "crate"])
    camera = scenes.cam((0, 0, 0), (1, 0, 0), near=0.5, far=100, fov_y_deg=60, aspect=1.5)
    with Culler(scene, resolution=(96, 64), ctx=ctx) as c:
        assert c.truth(camera)[1]
        for env in (Envelope(0.05, 2.0), Envelope(0.05, 2.0, any_roll=False), Envelope(0.0, 0.0)):
            assert c.cull(camera, envelope=env).state[1] == Visibility.VISIBLE, env


def test_what_a_turned_view_draws_before_its_far_plane_is_not_culled(ctx):
    """The far plane is a plane, not a sphere: a crate 118 away (6 wide), 25 degrees off the
    axis, lies 104-110 deep (beyond the far plane at 100) from the centre view and under 97
    (drawn) from the view turned 10 degrees away from it.  City-xl's path hid two such
    objects from a sampled view of its envelope (bench city-xl --envelope 2,10)."""
    phi = math.radians(25.0)
    centre = 118.0 * np.array([math.cos(phi), math.sin(phi), 0.0])
    scene = scenes.boxes_scene([(centre - 3.0, centre + 3.0)], ["crate"])
    kw = {"near": 0.5, "far": 100.0, "fov_y_deg": 60, "aspect": 1.5, "up": (0, 0, 1)}
    camera = scenes.cam((0, 0, 0), (1, 0, 0), **kw)
    turned = scenes.cam((0, 0, 0), (math.cos(-0.1745), math.sin(-0.1745), 0.0), **kw)   # 10 degrees away
    with Culler(scene, resolution=(96, 64), ctx=ctx) as c:
        assert not c.truth(camera)[0] and c.truth(turned)[0]                 # the premise
        for env in (Envelope(0.0, 10.0), Envelope(0.0, 10.0, any_roll=False), Envelope(1.0, 12.0)):
            assert c.cull(camera, envelope=env).state[0] == Visibility.VISIBLE, env


def test_envelope_holds_at_the_display_resolution(ctx):
    """Queries at a quarter of the display: the views of the envelope, drawn at the
    display's resolution, see nothing the pass hides."""
    scene, cams, _ = scenes.random_city(41, 300)
    rng = np.random.default_rng(41)
    hidden = 0
    with Culler(scene, resolution=(240, 135), display=(960, 540), ctx=ctx) as c:
        for env in (Envelope(0.5, 3.0, any_roll=False), Envelope(1.0, 5.0)):
            result = c.cull(cams[0], envelope=env)
            for view in sample_views(cams[0], env, 4, rng):
                assert not (c.renderer.visible_truth(view, display=True) & ~result.visible).any(), env
            hidden += int((~result.visible).sum())
    assert hidden > 0


@pytest.mark.parametrize("group", [1, 5, 10**9])
def test_the_polygon_proof_does_not_depend_on_order_chunks_or_groups(ctx, monkeypatch, group):
    """The proof is an OR over box-polygon pairs: the polygons' order, the chunks of boxes and
    the groups whose bounding boxes are tested first change the work only.  Polygons
    shuffled, chunks of 7 boxes and groups of 1, 5 or every box in one (the flat test) give
    the answer of the envelope pass's own inputs."""
    from core import envelope as envmod
    from core import umbra
    calls = []

    def spy(*a, **k):
        calls.append((a, k))
        return hidden_by_polygons(*a, **k)
    monkeypatch.setattr(envmod, "hidden_by_polygons", spy)
    scene, cams, _ = scenes.random_city(12, 300)
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        for cam in cams[:3]:
            c.cull(cam, envelope=Envelope(1.0, 5.0))
    monkeypatch.undo()
    rng = np.random.default_rng(12)
    proved = 0
    for (boxes, polys, *rest), k in calls:
        want = hidden_by_polygons(boxes, polys, *rest, **k)
        proved += int(want.sum())
        with monkeypatch.context() as m:
            m.setattr(umbra, "BOX_CHUNK", 7)
            m.setattr(umbra, "GROUP", group)
            assert np.array_equal(hidden_by_polygons(boxes, polys[rng.permutation(len(polys))], *rest, **k), want)
    assert calls and proved > 0


def _flat_polygon_proof(boxes, polys, distance, depth_guard=None):
    """Every box against every polygon, one at a time (the groups' reference)."""
    guard = np.zeros(len(boxes)) if depth_guard is None else depth_guard
    return np.array([any(hidden_by_polygons(boxes[i:i + 1], polys[p:p + 1], distance,
                                            depth_guard=guard[i:i + 1])[0] for p in range(len(polys)))
                     for i in range(len(boxes))], dtype=bool)


@pytest.mark.parametrize("seed", range(3))
def test_grouped_boxes_get_the_answer_of_each_box_alone(seed):
    """Boxes in three clusters (deep behind a polygon: groups hidden whole; around the eye,
    short of every polygon's plane: groups that miss every umbra; around the polygons:
    groups that straddle them) and
    scattered, with depth guards: the grouped proof hides exactly the boxes that a polygon
    hides when each box is tested alone."""
    from core import umbra
    rng = np.random.default_rng(300 + seed)
    polys = _random_polygons(rng, 10)
    g = umbra.GROUP
    n = 6 * g + 7                                              # a last group of 7
    centres = polys.mean(axis=1)[rng.integers(0, 10, n)] * rng.uniform(1.05, 2.5, (n, 1))
    deep = polys[0].mean(axis=0) * 1.5
    centres[:2 * g] = deep + rng.normal(scale=0.01, size=(2 * g, 3))
    centres[2 * g:4 * g] = rng.normal(scale=0.3, size=(2 * g, 3))
    half = rng.uniform(0.02, 1.0, (n, 1, 3))
    half[:4 * g] = 0.01
    boxes = np.concatenate([centres[:, None] - half, centres[:, None] + half], axis=1)
    guard = rng.uniform(0.0, 0.3, n) * (rng.random(n) < 0.5)
    guard[:2 * g] = 0.0
    distance = float(rng.uniform(0.1, 1.0))
    got = hidden_by_polygons(boxes, polys, distance, depth_guard=guard)
    assert np.array_equal(got, _flat_polygon_proof(boxes, polys, distance, guard))
    assert got[:2 * g].all() and not got[2 * g:4 * g].any()
    assert 0 < got[4 * g:].sum() < n - 4 * g


def test_the_polygon_proof_degenerate_inputs():
    """No boxes, no polygons, one box, boxes all at one point (no Morton span) and one more
    box than a group: the answers of each box alone."""
    from core import umbra
    square = np.array([[[-2, -2, -10], [2, -2, -10], [2, 2, -10], [-2, 2, -10]]], dtype=float)
    behind = np.array([[-0.5, -0.5, -14], [0.5, 0.5, -13]])
    beside = behind + (5.0, 0.0, 0.0)
    assert hidden_by_polygons(np.zeros((0, 2, 3)), square, 0.5).shape == (0,)
    assert hidden_by_polygons(behind[None], np.zeros((0, 4, 3)), 0.5).tolist() == [False]
    assert hidden_by_polygons(behind[None], square, 0.5).tolist() == [True]
    same = np.repeat(behind[None], umbra.GROUP * 2 + 1, axis=0)
    assert hidden_by_polygons(same, square, 0.5).all()
    mixed = np.concatenate([same[:umbra.GROUP], beside[None]])
    want = [True] * umbra.GROUP + [False]
    assert hidden_by_polygons(mixed, square, 0.5).tolist() == want
    assert hidden_by_polygons(mixed[::-1], square, 0.5).tolist() == want[::-1]
    # a polygon whose plane the ball reaches hides nothing, grouped or not
    assert not hidden_by_polygons(same, square, 10.5).any()


def test_morton_order_visits_each_octant_whole():
    """A 4 x 4 x 4 grid in Morton order: every run of 8 is one 2 x 2 x 2 cell, every run of 64
    the grid; a permutation for any points, the identity for one point repeated."""
    from core.umbra import morton_order
    grid = np.stack(np.meshgrid(*[np.arange(4.0)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    rng = np.random.default_rng(0)
    shuffled = grid[rng.permutation(len(grid))]
    order = morton_order(shuffled)
    assert sorted(order.tolist()) == list(range(64))
    cells = (shuffled[order] // 2).reshape(8, 8, 3)
    assert all((c == c[0]).all() for c in cells)
    assert len({tuple(c[0]) for c in cells}) == 8
    assert morton_order(np.ones((5, 3))).tolist() == list(range(5))
    assert morton_order(np.zeros((0, 3))).tolist() == []


def test_a_result_carries_the_envelope_it_holds_for(ctx):
    scene, cams, _ = scenes.random_city(2, 60)
    with Culler(scene, resolution=(64, 36), ctx=ctx) as c:
        assert c.cull(cams[0]).envelope is None                    # a point pass: its own view only
        env = Envelope(0.5, 5.0, any_roll=False)
        assert c.cull(cams[0], envelope=env).envelope == env
        assert c.cull(cams[0], envelope=(0.5, 5.0)).envelope == Envelope(0.5, 5.0)
        assert c.cull(cams[0], lights=[]).envelope is None        # no lights, no envelope: a point pass


@pytest.mark.parametrize("seed", [0, 1, 2, 5])
def test_the_cover_plan_leaves_the_extended_depth_as_every_window_makes_it(ctx, seed):
    """extended_depth computes windows only where cover_plan says a pixel may be covered:
    on random cities' envelope images (plans of nothing, a part, the whole image) it is
    every window's image (_extended_depth), pixel for pixel."""
    from core.envelope import _extended_depth, cover_plan, extended_depth
    scene, cams, _ = scenes.random_city(seed, 250)
    kinds, covered = set(), 0
    with Culler(scene, resolution=(161, 91), ctx=ctx) as c:
        for camera in cams[:4]:
            for env, near_eff in ((Envelope(0.0, 0.0), 0.0), (Envelope(0.02, 2.0), 0.1), (Envelope(0.5, 5.0), 0.6),
                                  (Envelope(2.0, 10.0), 2.2), (Envelope(0.3, 20.0, any_roll=False), 0.4)):
                view = envelope_camera(camera, env, 91)
                if view is None:
                    continue
                depth = c.renderer.read_texture_depth(c.renderer.envelope_depth(view.render, view.size))
                plan = cover_plan(depth, view.render, env.distance, near_eff)
                kinds.add("none" if plan is None else "whole" if plan[0] == (0, *depth.shape[:1], 0, depth.shape[1])
                          else "part")
                want = _extended_depth(depth, view.render, env, near_eff)
                got = extended_depth(depth, view.render, env, near_eff)
                assert np.array_equal(got, want), (seed, env)
                if plan is None:
                    assert np.isinf(want).all()
                else:
                    (y0, y1, x0, x1), last = plan
                    outside = np.ones(depth.shape, dtype=bool)
                    outside[y0:y1, x0:x1] = False
                    assert np.isinf(want[outside]).all()
                covered += int(np.isfinite(want).sum())
    assert covered > 0 and {"part", "whole"} <= kinds, kinds


@pytest.mark.parametrize("shape", [(3, 3), (5, 7), (64, 66), (130, 97)])
def test_the_cover_plan_on_a_flat_wall_and_on_an_empty_image(shape):
    """A wall square to the axis fills the image: pixels far enough from the border are
    covered and the plan holds them; an empty image covers nothing.  Sides that are no
    multiple of the plan's blocks, and images smaller than one block."""
    from core.camera import perspective
    from core.envelope import _extended_depth, cover_plan, extended_depth
    rows, cols = shape
    camera = Camera(np.eye(4), perspective(60.0, cols / rows, 0.1, 100.0))
    near, far = 0.1, 100.0
    z = 50.0
    ndc = (far + near - 2.0 * near * far / z) / (far - near)
    wall = np.full(shape, np.float32(0.5 * ndc + 0.5))
    for env in (Envelope(0.05, 1.0), Envelope(0.0, 0.0)):
        want = _extended_depth(wall, camera, env, 0.0)
        assert np.array_equal(extended_depth(wall, camera, env, 0.0), want)
        if min(shape) > 8:
            assert np.isfinite(want).any()
        empty = np.ones(shape, dtype=np.float32)
        # a window of 3 x 3 holds no parallax (D > 0): only the blocks are read
        assert cover_plan(empty, camera, env.distance) is None or env.distance == 0.0
        assert np.isinf(extended_depth(empty, camera, env, 0.0)).all()


def test_the_image_schedule_waits_longer_after_each_useless_image():
    from core.envelope import ImageSchedule
    s = ImageSchedule()
    drawn = []
    for hidden in [0] * 6 + [3] + [0] * 3:
        while not s.draws():
            drawn.append(False)
        drawn.append(True)
        s.drew(hidden)
    # six useless images: waits of 1, 2, 4, 8, 8, 8; one that hides: no wait; then 1, 2
    runs = "".join("d" if d else "." for d in drawn)
    assert runs == "d.d..d....d" + "........d" * 3 + "d.d..d", runs
    # during motion: only while the last image hid something, and no wait counted down
    assert not s.draws(probe=False) and s.left == 4
    s.drew(2)
    assert s.draws(probe=False) and s.draws(probe=False)
    s.drew(0)
    assert not s.draws(probe=False)
    s.reset()
    assert s.draws()


def test_passes_without_the_image_hide_nothing_any_view_sees_and_a_fresh_pass_draws_it(ctx):
    """A random city's path with the 2,10 envelope: the passes that leave the image out
    (after one whose image hid nothing) still hide nothing a view of the envelope sees;
    a fresh pass draws the image again."""
    scene, cams, _ = scenes.random_city(8, 300)
    env = Envelope(2.0, 10.0)
    rng = np.random.default_rng(8)
    skipped = 0
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        for camera in cams:
            r = c.cull(camera, envelope=env)
            skipped += r.stats.envelope_image_hidden is None
            assert not (_seen_from(c, sample_views(camera, env, 8, rng)) & ~r.visible).any()
        c.envelope_image.wait = c.envelope_image.left = 4
        assert c.cull(cams[0], envelope=env, fresh=True).stats.envelope_image_hidden is not None
        c.envelope_image.left = 4
        c.forget()
        assert c.cull(cams[0], envelope=env).stats.envelope_image_hidden is not None
    assert skipped > 0


@pytest.mark.parametrize("seed", range(4))
def test_covering_holds_every_sampled_view_and_widens_as_asked(seed):
    """The envelope of a camera's sampled views (a baked frame's sub-frames) holds each of
    them; widened by w, its distance and turn are (1 + w) times the largest; a lens change
    or a turn past the limit gives False, no motion None."""
    from core.envelope import MAX_COVER_TURN_DEG, covering
    rng = np.random.default_rng(seed)
    centre = Camera.look_at((0, 0, 1), (5, 0, 1), (0, 0, 1), 50.0)
    views = [Camera.look_at(tuple(rng.normal(0, 0.5, 3) + (0, 0, 1)),
                            tuple((5, 0, 1) + rng.normal(0, 0.4, 3)), (0, 0, 1), 50.0) for _ in range(5)]
    env = covering(centre, views)
    assert all(env.holds(centre, v) for v in views) and not env.any_roll
    wide = covering(centre, views, widen=0.25)
    assert math.isclose(wide.distance, 1.25 * env.distance, rel_tol=1e-6)
    assert math.isclose(wide.angle_deg, 1.25 * env.angle_deg, rel_tol=1e-6)
    assert covering(centre, [centre, centre]) is None and covering(centre, []) is None
    assert covering(centre, views + [Camera.look_at((0, 0, 1), (5, 0, 1), (0, 0, 1), 40.0)]) is False
    turned = Camera.look_at((0, 0, 1), (5 * math.cos(math.radians(MAX_COVER_TURN_DEG + 5)),
                                        5 * math.sin(math.radians(MAX_COVER_TURN_DEG + 5)), 1), (0, 0, 1), 50.0)
    assert covering(centre, [turned]) is False


def test_polygon_weights_favour_wide_faces_that_face_the_eye():
    from core.umbra import polygon_weights, width_factor

    def quad(centre, u, v):
        c, u, v = (np.asarray(a, dtype=float) for a in (centre, u, v))
        return np.array([c - u - v, c + u - v, c + u + v, c - u + v])

    facing = quad((0, 0, 50), (10, 0, 0), (0, 10, 0))          # 20 x 20, facing the eye at 50
    grazing = quad((0, 0, 50), (10, 0, 0), (0, 0, 10))         # the same, edge-on
    narrow = quad((0, 0, 50), (1, 0, 0), (0, 100, 0))          # 2 x 200: the same area, facing
    near_small = quad((0, 0, 10), (2, 0, 0), (0, 2, 0))        # 4 x 4 at 10: the same solid angle
    w = polygon_weights(np.stack([facing, grazing, narrow, near_small]), 8.0)
    assert w[1] < 1e-12 * w[0]                                  # edge-on: no solid angle
    # of the same solid angle the narrow one keeps (2 / 16)^2, the small near one (4 / 16)^2:
    # a wide far face outweighs both from a ball of radius 8
    assert np.isclose(w[2] / w[0], width_factor(2.0, 8.0) / width_factor(20.0, 8.0), rtol=1e-3)
    assert w[0] > w[3] > w[2]
    assert np.isclose(polygon_weights(near_small[None], 0.0)[0] / polygon_weights(facing[None], 0.0)[0],
                      (16 / 10 ** 2) / (400 / 50 ** 2), rtol=1e-6)   # no ball: the solid angle alone
    assert np.isclose(width_factor(32.0, 8.0), 1.0) and width_factor(4.0, 0.0) == 1.0


def test_the_envelope_finds_a_far_wall_behind_more_near_clutter_than_it_tries():
    """More near clutter than umbra.OBJECTS (boxes of 0.8 within 2.5-3.5 units of the eye,
    larger in angle than the wall, hiding nothing from a ball of 2 units) and one far wall:
    the wall's polygons are still tried, and the box behind it is hidden from the whole
    envelope."""
    from core import umbra
    from core.envelope import occluder_polygons
    rng = np.random.default_rng(5)
    items = []
    for _ in range(umbra.OBJECTS + 40):                          # around the eye, behind it
        d = rng.normal(size=3)
        d[1] = -abs(d[1]) - 0.5
        c = d / np.linalg.norm(d) * rng.uniform(2.9, 3.9)
        items.append((tuple(c - 0.4), tuple(c + 0.4)))
    items.append(((-20.0, 150.0, -20.0), (20.0, 151.0, 20.0)))  # the wall, 40 x 40, 150 ahead
    items.append(((-0.5, 170.0, -0.5), (0.5, 171.0, 0.5)))      # behind it
    scene = scenes.boxes_scene(items)
    camera = scenes.cam((0, 0, 0), (0, 1, 0), near=0.05, far=500, fov_y_deg=60, aspect=1.0)
    with Culler(scene, (64, 64)) as c:
        polys = occluder_polygons(c, camera.eye, 2.0)
        # the wall's facing side (camera-relative y = 150) is among the polygons tried
        assert np.any(np.all(np.isclose(polys[:, :, 1], 150.0), axis=1))
        r = c.cull(camera, envelope=Envelope(2.0, 5.0, any_roll=False), fresh=True)
    assert not r.visible[-1]
    assert r.visible[-2]


def _street():
    """A ground slab (top at z = 0), a facade standing on it at x = 10 (10 wide, 3.2 high)
    and a crate on the ground behind it; the eye 1.7 above the ground, looking +x."""
    boxes = [((-50, -50, -0.2), (50, 50, 0.0)), ((10, -5, 0.0), (10.3, 5, 3.2)), ((14, -1, 0.0), (15, 1, 0.7))]
    scene = scenes.boxes_scene(boxes, ["ground", "facade", "crate"])
    camera = scenes.cam((0, 0, 1.7), (1, 0, 1.7), near=0.1, far=200, fov_y_deg=50, aspect=1.5)
    return scene, camera


def test_live_envelopes_keep_their_eyes_above_the_ground_and_then_a_facade_hides_what_stands_behind(ctx):
    """The ball of 2 reaches 0.3 under the ground: from there a ray to the crate passes
    under the facade's lower edge (through the ground), so the facade alone proves
    nothing for the whole ball.  Live mode's envelope (eyes kept above a floor) finds the
    ground, keeps its eyes 0.425 above it (a quarter of the eye's height), and there the
    facade alone hides the crate; no sampled view of that envelope sees it."""
    scene, camera = _street()
    with Culler(scene, resolution=(120, 80), ctx=ctx) as c:
        ball = c.cull(camera, envelope=Envelope(2.0, 10.0, any_roll=False))
        live = c.cull(camera, envelope=Envelope(2.0, 10.0, any_roll=False, above_floor=True))
        seen = _seen_from(c, sample_views(camera, live.envelope, 60, np.random.default_rng(2)))
    assert ball.envelope.floor is None and ball.state[2] == Visibility.VISIBLE
    assert live.envelope.floor == pytest.approx((0.0, 0.0, 1.0, 1.7 - 0.75 * 1.7))
    assert live.state[2] == Visibility.OCCLUDED
    assert not (seen & ~live.visible).any() and not seen[2]


def test_no_floor_where_the_ball_stays_above_it_or_nothing_lies_under_the_eye(ctx):
    scene, camera = _street()
    high = scenes.cam((0, 0, 2.5), (1, 0, 2.5), near=0.1, far=200, fov_y_deg=50, aspect=1.5)
    beside = scenes.cam((0, 80, 1.7), (1, 80, 1.7), near=0.1, far=200, fov_y_deg=50, aspect=1.5)
    with Culler(scene, resolution=(120, 80), ctx=ctx) as c:
        assert c.cull(high, envelope=Envelope(2.0, 10.0, above_floor=True)).envelope.floor is None
        assert c.cull(beside, envelope=Envelope(2.0, 10.0, above_floor=True)).envelope.floor is None
        assert c.cull(camera, envelope=Envelope(0.0, 10.0, above_floor=True)).envelope.floor is None


def test_a_floor_is_checked_by_holds_lasts_and_sampled_views():
    """Views under the floor's plane are not the envelope's; live mode's checks ask for the
    height a sinking eye needs (measured velocities and last step), a level move none."""
    from core.motion import LivePolicy
    _, camera = _street()
    env = Envelope(2.0, 10.0, any_roll=False, floor=(0.0, 0.0, 1.0, 0.5))
    low = scenes.cam((0, 0, 0.4), (1, 0, 0.4), near=0.1, far=200, fov_y_deg=50, aspect=1.5)
    assert env.holds(camera, camera) and not env.holds(camera, low)
    assert env.height(camera.eye) == pytest.approx(1.2) and Envelope(1, 1).height(camera.eye) == math.inf
    views = sample_views(camera, env, 200, np.random.default_rng(4))
    assert min(v.eye[2] for v in views) >= 0.5 and min(v.eye[2] for v in views) < 0.8
    policy = LivePolicy()
    level, down = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0])
    assert policy.lasts(camera, env, camera, 0.3, 1.0, 0.0, 0.1, 0.0, velocities=[level], step_eye=0.1 * level)
    assert not policy.lasts(camera, env, camera, 0.3, 1.0, 0.0, 0.1, 0.0, velocities=[level, 5 * down],
                            step_eye=0.1 * level)
    assert not policy.safe(camera, env, camera, 0.7, 0.0, step_eye=0.7 * down)      # 2 steps: 1.4 > 1.2
    assert policy.safe(camera, env, camera, 0.5, 0.0, step_eye=0.5 * level)


@pytest.mark.parametrize("floor", [(0.0, 0.0, 2.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0, math.nan)])
def test_a_bad_floor_gets_one_clear_error(floor):
    with pytest.raises(OccError, match="floor"):
        Envelope(1.0, 1.0, floor=floor)


def _extreme_eyes(camera, envelope, count=12):
    """Views (``camera``'s direction) from the extremes of the envelope's eyes: around the
    rim where its floor cuts the ball (just above it), and the ball's surface along the
    axes where it stays above the floor."""
    eye, up = camera.eye, np.array(envelope.floor[:3])
    level = envelope.height(eye)                                  # the eye above the cut
    r = math.sqrt(max(envelope.distance ** 2 - level ** 2, 0.0))
    a = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    points = [eye - (level - 1e-6) * up + 0.999 * r * (math.cos(t) * a + math.sin(t) * b)
              for t in np.linspace(0, 2 * np.pi, count, endpoint=False)]
    points += [eye + 0.999 * envelope.distance * s for s in (a, -a, b, -b, up)]
    d = camera.direction
    return [scenes.cam(p, p + d, near=0.05, far=150, fov_y_deg=55, aspect=1.5) for p in points]


@pytest.mark.parametrize("seed", range(8))
def test_random_streets_hide_nothing_a_view_kept_above_the_ground_sees(ctx, seed):
    """Seeded streets on a ground slab: facades 6-14 ahead (standing on it, or with a gap
    under them that low eyes see through), crates behind them (on the ground or floating
    low), the eye 0.4-2.5 above the ground, a ball of 1-3 that reaches through it, a turn
    of up to 15 degrees.  Live mode's envelope keeps its
    eyes above the ground; no view of the envelope the pass used sees an object it hides:
    the frame's own, seeded views, and views from the envelope's extremes (around the rim
    where the floor cuts the ball, and the ball's surface).  The floor is found each time
    and proves more than the whole ball at least once."""
    rng = np.random.default_rng(700 + seed)
    boxes = [((-100, -100, -0.3), (100, 100, 0.0))]
    for _ in range(int(rng.integers(1, 4))):
        x, y = rng.uniform(6, 14), rng.uniform(-8, 2)
        z0 = 0.0 if rng.random() < 0.5 else rng.uniform(0.2, 1.0)     # on the ground, or a gap under it
        boxes.append(((x, y, z0), (x + 0.3, y + rng.uniform(3, 10), z0 + rng.uniform(1.5, 6))))
    for _ in range(40):
        x, y = rng.uniform(8, 30), rng.uniform(-8, 8)
        z0 = 0.0 if rng.random() < 0.7 else rng.uniform(0.05, 2)
        boxes.append(((x, y, z0), (x + rng.uniform(0.2, 1.5), y + rng.uniform(0.2, 1.5), z0 + rng.uniform(0.2, 1.5))))
    scene = scenes.boxes_scene(boxes)
    floors = proved_more = 0
    with Culler(scene, resolution=(160, 100), ctx=ctx) as c:
        for k in range(4):
            height = rng.uniform(0.4, 2.5)
            eye = (0.0, rng.uniform(-2, 2), height)
            target = (10.0, eye[1] + rng.uniform(-2, 2), height + rng.uniform(-0.8, 0.4))
            camera = scenes.cam(eye, target, near=0.05, far=150, fov_y_deg=55, aspect=1.5)
            distance = height + rng.uniform(0.1, 1.0)
            env = Envelope(distance, rng.uniform(0, 15), any_roll=bool(rng.random() < 0.5), above_floor=True)
            r = c.cull(camera, envelope=env)
            floors += r.envelope.floor is not None
            ball = c.cull(camera, envelope=replace(env, above_floor=False))
            proved_more += int((~r.visible).sum() > (~ball.visible).sum())
            views = [camera] + sample_views(camera, r.envelope, 20, rng) + _extreme_eyes(camera, r.envelope)
            for v in views:
                assert r.envelope.holds(camera, v)
            seen = _seen_from(c, views)
            assert not (seen & ~r.visible).any(), (seed, k, np.flatnonzero(seen & ~r.visible))
    assert floors == 4 and proved_more >= 1
