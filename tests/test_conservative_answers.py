"""Conservative answers from the engine: answers that do not hang on sample rounding or
depth rounding, a coherent memory that never makes a pass worse than a fresh one,
NaN or infinite values that affect only their own object, a lower query resolution
that keeps what the display shows, and overlapping boxes sharing one multiple query."""

import warnings

import numpy as np
import pytest

from core import Camera, Culler, Scene, Visibility
from tests import scenes

QUERY_STRATEGIES = ("stopwait", "leaf_stopwait", "om_single", "om", "om_multi", "om_coherent")


@pytest.mark.parametrize("strategy", QUERY_STRATEGIES)
def test_thin_slab_edge_on_is_kept_whatever_the_sample_rounding(ctx, strategy):
    """``stopwait`` and ``om`` once culled a slab seen edge-on (about 1.4 pixels
    tall) that another renderer lights.  Every slab that a renderer sampling a
    little off this one's pixel centres (up to 0.3 pixel, either way) sees, at
    1200x800, is kept."""
    w, h = 1200, 800
    scene, cam = scenes.slabs_behind_a_wall_edge(w, h)
    with Culler(scene, (w, h), strategy=strategy, ctx=ctx) as c:
        seen = np.zeros(len(scene), dtype=bool)
        for dy in (-0.3, -0.15, 0.0, 0.15, 0.3):
            seen |= c.truth(scenes.shifted(cam, 0.0, dy, w, h))
        assert seen[1:11].any() and not seen[1:11].all()     # the set-up straddles pixel centres
        r = c.cull(cam, fresh=True)
    missed = [scene.names[i] for i in np.flatnonzero(seen & ~r.visible)]
    assert not missed, f"{strategy} culled {missed}, which a shifted renderer shows"


@pytest.mark.parametrize("strategy", QUERY_STRATEGIES)
def test_depth_ties_behind_a_wall_at_one_degree_stay_visible(ctx, strategy):
    """At a 1 degree field of view, camera 688 units away, near 0.01, one
    24-bit depth step is about 2.9 units there; objects just behind the wall's face
    (up to about 1.5 steps: each surface's depth is rounded to the grid, and
    another renderer rounds its own way) are depth ties and count as visible.
    The old guard (relative to the box's size only) culled those from 3.5 units
    on.  One far behind is still culled."""
    d = 688.0
    boxes = [((d, -8.0, -8.0), (d + 2.0, 8.0, 8.0))]                    # the wall, face at x = 688
    names = ["wall"]
    for k, gap in enumerate((0.05, 0.5, 1.5, 2.5, 3.5, 4.5)):
        y = -5.0 + 2.0 * k
        boxes.append(((d + gap, y, -1.0), (d + gap + 0.5, y + 1.0, 1.0)))    # inside the wall, face just behind
        names.append(f"tie_{gap}")
    boxes.append(((d + 60.0, -2.0, -2.0), (d + 62.0, 2.0, 2.0)))
    names.append("far_behind")
    scene = scenes.boxes_scene(boxes, names)
    cam = Camera.look_at((0, 0, 0), (1, 0, 0), up=(0, 0, 1), fov_y_deg=1.0, aspect=1.5, near=0.01,
                         far=2000.0)
    with Culler(scene, (96, 64), strategy=strategy, ctx=ctx) as c:
        r = c.cull(cam)
    state = dict(zip(scene.names, r.state, strict=True))
    ties = [n for n in names if n.startswith("tie_") and state[n] != Visibility.VISIBLE]
    assert not ties, f"{strategy} culled depth ties {ties}"
    assert state["far_behind"] == Visibility.OCCLUDED


def test_depth_step_at_688_units_is_about_2_9_units():
    """The depth step at 688 units with near 0.01 and a 24-bit buffer is about 2.9 units."""
    from core.tolerance import tol
    near, far, dist = 0.01, 2000.0, 688.0
    step = dist ** 2 * (far - near) / (near * far * 2.0 ** tol.depth_bits)
    assert 2.7 < step < 3.0


def front_and_back(n=200, seed=3):
    """A random city with cameras looking at it, away from it and back."""
    scene, cams, _ = scenes.random_city(seed, n)
    front = cams[0]
    eye = front.eye
    target = eye - (front.direction * 10.0)
    back = Camera.look_at(eye, target, up=(0, 0, 1), fov_y_deg=60, aspect=1.5, near=0.1, far=1000)
    return scene, front, back


@pytest.mark.parametrize("strategy", ["om_coherent", "om_multi"])
def test_look_away_and_back_hides_as_many_as_a_fresh_pass(ctx, strategy):
    """One pass after looking away and back hides as many objects as
    a fresh cull of the same view (the memory of last pass's visible leaves is
    dropped after a camera cut)."""
    scene, front, back = front_and_back()
    with Culler(scene, (160, 120), strategy=strategy, ctx=ctx) as c:
        fresh = c.cull(front, fresh=True)
        assert (fresh.state == Visibility.OCCLUDED).sum() > 10
        for _ in range(3):
            c.cull(back)
            again = c.cull(front)
            assert (again.state == Visibility.OCCLUDED).sum() >= (fresh.state == Visibility.OCCLUDED).sum()
            assert np.array_equal(again.state, fresh.state)


def test_coherent_memory_is_kept_over_small_moves(ctx):
    """The cut detector does not switch the memory off on a walkthrough: consecutive
    frames that barely move reuse it (no fresh pass), and stay conservative."""
    scene, front, _ = front_and_back()
    eye, d = front.eye, front.direction
    with Culler(scene, (160, 120), strategy="om_coherent", ctx=ctx) as c:
        fresh = []
        for k in range(4):
            cam = Camera.look_at(eye + 0.01 * k * d, eye + (10 + 0.01 * k) * d, up=(0, 0, 1),
                                 fov_y_deg=60, aspect=1.5, near=0.1, far=1000)
            truth = c.truth(cam)
            r = c.cull(cam)
            assert not (truth & ~r.visible).any()
            fresh.append(r.stats.fresh)
        assert fresh == [1, 0, 0, 0]
        assert c.cull(cam, fresh=True).stats.fresh == 1


@pytest.mark.parametrize("strategy", ["vfc", "stopwait", "om", "om_multi", "om_coherent", "oracle"])
def test_nan_object_is_named_kept_visible_and_never_an_occluder(ctx, strategy):
    """One NaN in an object's matrix or vertices names that object
    in a warning; it stays VISIBLE, is never drawn as an occluder, and every other
    object is culled as usual."""
    scene = scenes.invalid_scene()
    assert scene.invalid_names == ["bad_wall", "bad_mesh"]
    cam = scenes.cam((-10, 0, 0), (0, 0, 0), up=(0, 0, 1), far=100)
    with pytest.warns(UserWarning, match="'bad_wall', 'bad_mesh'"):
        culler = Culler(scene, (96, 64), strategy=strategy, ctx=ctx)
    with culler as c:
        truth = c.truth(cam)
        r = c.cull(cam, truth=truth)
        state = dict(zip(scene.names, r.state, strict=True))
        assert state["bad_wall"] == state["bad_mesh"] == Visibility.VISIBLE
        assert state["front"] == state["wall"] == Visibility.VISIBLE
        if strategy != "vfc":
            assert state["behind_a"] == state["behind_b"] == Visibility.OCCLUDED
        assert r.stats.invalid_objects == 2
        assert c.invalid_names == ["bad_wall", "bad_mesh"]
        assert not (truth & ~r.visible).any()


def test_nan_matrix_set_later_affects_only_that_object(ctx):
    """set_matrices with a NaN no longer raises and blocks every cull: that object is
    kept visible, the others culled; a finite matrix later makes it an occluder again."""
    scene = scenes.invalid_scene(bad_matrix=False, bad_vertices=False)
    cam = scenes.cam((-10, 0, 0), (0, 0, 0), up=(0, 0, 1), far=100)
    bad = scene.names.index("bad_wall")
    good = scene.matrices[bad].copy()
    with Culler(scene, (96, 64), strategy="om_multi", ctx=ctx) as c:
        r = c.cull(cam)
        assert r.state[bad] == Visibility.VISIBLE
        assert (r.state[[0, 1, 2, 3, 5]] == Visibility.OCCLUDED).all()     # the whole wall hides them
        broken = good.copy()
        broken[1, 1] = np.inf
        with pytest.warns(UserWarning, match="'bad_wall'"):
            c.set_matrices([bad], broken[None])
        r = c.cull(cam)
        state = dict(zip(scene.names, r.state, strict=True))
        assert state["bad_wall"] == state["wall"] == state["front"] == Visibility.VISIBLE
        assert state["behind_a"] == state["behind_b"] == Visibility.OCCLUDED
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            c.set_matrices([bad], good[None])
        assert (c.cull(cam).state[[0, 1, 2, 3, 5]] == Visibility.OCCLUDED).all()


def test_every_object_invalid_culls_nothing(ctx):
    m = np.full((2, 4, 4), np.nan)
    scene = Scene.from_arrays(["a", "b"], [(scenes.UNIT_BOX_V, scenes.UNIT_BOX_F)], [0, 0], m)
    with pytest.warns(UserWarning):
        c = Culler(scene, (32, 32), ctx=ctx)
    with c:
        r = c.cull(scenes.cam((-10, 0, 0), (0, 0, 0)))
        assert r.visible.all() and r.stats.queries == 0


@pytest.mark.parametrize("strategy", ["stopwait", "om", "om_multi", "om_coherent"])
def test_lower_query_resolution_keeps_what_the_display_shows(ctx, strategy):
    """Culling at a quarter of the display resolution per side with ``display=`` given: the
    renderer keeps each query pixel's farthest display depth, the engine grows
    boxes by a query pixel, and a post seen through a 1-pixel slit of the display
    is kept (at the lower resolution alone the slit closes)."""
    scene, (cam,), _ = scenes.slit_wall(1)
    display = scenes.SLIT_RESOLUTION
    query = (display[0] // 4, display[1] // 4)         # without display= the slit closes here
    with Culler(scene, display, strategy="vfc", ctx=ctx) as full:
        truth = full.truth(cam)
    assert truth[scene.names.index("post_slit")]
    with Culler(scene, query, strategy=strategy, ctx=ctx, display=display) as c:
        if not c.conservative_display:
            pytest.skip("this renderer has no conservative lower query resolution")
        r = c.cull(cam)
    assert not (truth & ~r.visible).any()
    assert r.state[scene.names.index("post_hidden")] == Visibility.OCCLUDED


def test_test_lists_follow_the_papers_rule_in_the_engine(ctx):
    """Boxes behind a wall whose screen rectangles overlap their neighbours'
    by a little go into one multiple query (each still has free tiles in the list's
    map); the old rule (no overlap with a box taken) needed a list per neighbour."""
    boxes = [((0, -20, -20), (0.2, 20, 20))]
    for k in range(6):                       # side by side, each overlapping the next on screen
        boxes.append(((3 + 0.3 * k, -6 + 2 * k, -1), (3.5 + 0.3 * k, -3.5 + 2 * k, 1)))
    scene = scenes.boxes_scene(boxes)
    cam = scenes.cam((-10, 0, 0), (0, 0, 0), up=(0, 0, 1), far=100)
    with Culler(scene, (96, 64), strategy="om", ctx=ctx) as c:
        r = c.cull(cam)
    assert (r.state[1:] == Visibility.OCCLUDED).all()
    assert r.stats.multiple_queries == 1 and r.stats.queries == 6
