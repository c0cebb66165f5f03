"""The strategy registry, the adaptive default and the per-pass counters."""

import numpy as np
import pytest

from core import Culler, Visibility
from core.cull import DEFAULT_STRATEGY, REGISTRY, STRATEGIES, Auto, CullPass, Strategy, make_strategy
from tests import scenes


def test_registry_is_the_one_list():
    assert STRATEGIES == tuple(REGISTRY)
    assert DEFAULT_STRATEGY in REGISTRY and REGISTRY[DEFAULT_STRATEGY].default_candidate
    for name, info in REGISTRY.items():
        assert info.name == name and info.label and info.description
        s = make_strategy(name)
        assert isinstance(s, Strategy)
    assert {"leaf_stopwait", "om_single", "auto"} <= set(STRATEGIES)
    assert [n for n, i in REGISTRY.items() if i.needs_truth] == ["oracle"]


def test_each_engine_has_its_own_strategy_state():
    a, b = make_strategy("om_coherent"), make_strategy("om_coherent")
    assert a is not b
    a.max_tests = 3
    assert b.max_tests == 8


def culled(result):
    return int((result.state == Visibility.OCCLUDED).sum())


def test_auto_tests_occlusion_where_triangles_are_dear(ctx):
    scene, cams, _ = scenes.random_city(11, 300)
    with Culler(scene, (128, 96), strategy="auto", ctx=ctx) as c:
        c.strategy.costs = {"tri_ms": 1e3, "round_trip_ms": 0.0, "vfc_cpu_ms": 0.0}
        c.strategy.learn_count = 2                                    # the costs are known: no learning pass
        for _ in range(2):
            for cam in cams:
                truth = c.truth(cam)
                r = c.cull(cam)
                assert r.stats.occlusion_pass == 1 and culled(r) > 0
                assert not (truth & ~r.visible).any()


def test_auto_falls_back_to_frustum_culling_where_tests_cannot_pay(ctx):
    """Triangles that cost nothing: after ``LOSSES`` passes the tests do not pay,
    frustum culling alone, with one occlusion probe every ``PROBE_EVERY`` passes."""
    scene, cams, _ = scenes.random_city(11, 300)
    cam = cams[0]
    with Culler(scene, (128, 96), strategy="auto", ctx=ctx) as c:
        c.strategy.costs = {"tri_ms": 0.0, "round_trip_ms": 1.0, "vfc_cpu_ms": 0.0}
        c.strategy.learn_count = 2                                    # the costs are known: no learning pass
        c.strategy.LEARN = 0.0                                        # keep the costs given (no timing in tests)
        c.strategy.PROBE_SLOWER = c.strategy.FIRST_SLOWER = float("inf")
        modes = [c.cull(cam).stats.occlusion_pass for _ in range(Auto.LOSSES + Auto.PROBE_EVERY + 2)]
    assert modes[:Auto.LOSSES] == [1] * Auto.LOSSES
    assert modes[Auto.LOSSES:Auto.LOSSES + Auto.PROBE_EVERY] == [0] * Auto.PROBE_EVERY
    assert modes[Auto.LOSSES + Auto.PROBE_EVERY] == 1                     # the probe
    assert modes[-1] == 0


def test_auto_probes_less_often_while_the_probes_lose(ctx):
    """Where the tests never pay, each losing probe doubles the interval before the
    next (16, 32, 64 frustum-only passes, at most ``PROBE_MAX``); a frustum-only pass
    much slower than the last test pass probes at once and restarts at 16."""
    scene, cams, _ = scenes.random_city(11, 300)
    cam = cams[0]
    with Culler(scene, (128, 96), strategy="auto", ctx=ctx) as c:
        a = c.strategy
        a.costs = {"tri_ms": 0.0, "round_trip_ms": 1.0, "vfc_cpu_ms": 0.0}
        a.learn_count, a.LEARN = 2, 0.0
        a.PROBE_SLOWER = a.FIRST_SLOWER = float("inf")
        modes = [c.cull(cam).stats.occlusion_pass for _ in range(Auto.LOSSES + 16 + 1 + 32 + 1 + 64 + 1 + 5)]
        probes = [i for i, m in enumerate(modes) if m][Auto.LOSSES:]
        assert np.diff(probes).tolist() == [33, 65] and probes[0] == Auto.LOSSES + 16
        assert a.probe_every == 128 == Auto.PROBE_MAX
        a.PROBE_SLOWER = a.FIRST_SLOWER = 0.0                       # any frustum pass is "much slower"
        a.last_test_ms = 0.0
        assert c.cull(cam).stats.occlusion_pass == 0 and a.probe_every == Auto.PROBE_EVERY
        assert c.cull(cam).stats.occlusion_pass == 1                 # the probe, at once
        assert a.probe_every == 2 * Auto.PROBE_EVERY                    # lost: 32 from the restart


def test_auto_learns_from_a_real_frustum_only_pass(ctx):
    """The first pass tests occlusion (its answer equals a fresh om_coherent pass's);
    the second draws the frustum and so learns what a triangle costs here."""
    scene, cams, _ = scenes.random_city(5, 300)
    with Culler(scene, (96, 64), strategy="auto", ctx=ctx) as c:
        a = c.cull(cams[0])
        assert a.stats.occlusion_pass == 1 and c.strategy.costs["round_trip_ms"] > 0.0
        b = c.cull(cams[0])
        assert b.stats.occlusion_pass == 0 and c.strategy.costs["tri_ms"] > 0.0
        assert not (b.state == Visibility.OCCLUDED).any()
    with Culler(scene, (96, 64), strategy="om_coherent", ctx=ctx) as c:
        fresh = c.cull(cams[0])
    assert np.array_equal(a.state, fresh.state)


@pytest.mark.parametrize("strategy", ["om_multi", "two_pass", "gpu"])
def test_query_pixels_off_changes_no_answer(ctx, strategy):
    """``Culler(query_pixels=False)`` (the add-on's) skips only the count of the pixels the
    query boxes rasterise: the same states and every other counter, pass after pass."""
    scene, cams, _ = scenes.random_city(5, 300)
    with Culler(scene, (128, 96), strategy=strategy, ctx=ctx) as on, \
            Culler(scene, (128, 96), strategy=strategy, ctx=ctx, query_pixels=False) as off:
        counted = 0
        for cam in list(cams[:3]) + [cams[0]]:
            a, b = on.cull(cam), off.cull(cam)
            assert np.array_equal(a.state, b.state)
            assert (a.stats.queries, a.stats.query_rect_pixels) == (b.stats.queries, b.stats.query_rect_pixels)
            assert b.stats.query_raster_pixels == 0
            counted += a.stats.query_raster_pixels
        assert counted > 0                       # (the gpu strategy's first pass is om_coherent's)


@pytest.mark.parametrize("strategy", ["vfc", "om_multi", "oracle"])
def test_pass_counters(ctx, strategy):
    """CPU time outside GL, GL calls and blocking reads (where the renderer counts
    them), and the query pixels the boxes rasterise (never more than their
    rectangles')."""
    scene, cams, _ = scenes.random_city(11, 300)
    with Culler(scene, (128, 96), strategy=strategy, ctx=ctx) as c:
        r = c.cull(cams[0], truth=c.truth(cams[0]))
    s = r.stats
    assert 0.0 <= s.cpu_ms <= s.total_ms
    assert s.gl_ms + s.cpu_ms == pytest.approx(s.total_ms, rel=1e-6, abs=1e-6)
    assert s.nodes_visited > 0
    if hasattr(c.renderer, "counters"):
        assert s.gl_calls >= 1 and s.blocking_reads >= 0
    if strategy == "om_multi":
        assert 0 < s.query_raster_pixels <= s.query_rect_pixels
        assert s.triangles_occluded > 0
    else:
        assert s.queries == 0 and s.query_raster_pixels == 0


def test_frustum_leaves_below_carry_their_rectangles(ctx):
    """Stage 3's leaves (``frustum_leaves_below``, the nodes between reached without
    rectangles) are the frustum's leaves below the root, each with the rectangle, tiles
    and distance a full reach gives it."""
    from core.cull.stages import frustum_leaves_below
    scene, cams, _ = scenes.random_city(11, 300)
    with Culler(scene, (128, 96), strategy="om_multi", ctx=ctx) as c:
        for cam in cams[:3]:
            full = CullPass(c.hierarchy, c.renderer, cam, c.options, c.scene_size)
            want = np.sort(full.frustum_leaves(geometry=True))
            f = CullPass(c.hierarchy, c.renderer, cam, c.options, c.scene_size)
            got = np.sort(frustum_leaves_below(f, f.root()))
            assert len(got) and np.array_equal(got, want)
            assert f.has_geometry[got].all()
            for a in ("rects", "tiles", "dist", "crosses"):
                assert np.array_equal(getattr(f, a)[got], getattr(full, a)[want]), a


def test_outline_pixels_of_a_box_facing_the_camera(ctx):
    """A box seen straight on rasterises its front face's area, in pixels."""
    scene = scenes.boxes_scene([((0, -20, -20), (0.2, 20, 20))])
    cam = scenes.cam((-10, 0, 0), (0, 0, 0), up=(0, 0, 1), aspect=1.0, far=100, ortho_height=8.0)
    with Culler(scene, (64, 64), strategy="vfc", ctx=ctx) as c:
        f = CullPass(c.hierarchy, c.renderer, cam, c.options, c.scene_size)
        box = np.array([[[5.0, -1.0, -1.0], [6.0, 1.0, 1.0]]]) - cam.eye        # 2 x 2 units = 16 x 16 px
        assert f.outline_pixels(box)[0] == pytest.approx(256.0)


def test_two_pass_uses_at_most_two_batches_once_coherent(ctx):
    """After its first (om_multi) pass, two_pass tests everything in at most two
    multiple queries a pass, never culls what the truth shows, and still culls."""
    from core import Camera
    scene, cams, _ = scenes.random_city(11, 300)
    eye, d = cams[0].eye, cams[0].direction
    with Culler(scene, (128, 96), strategy="two_pass", ctx=ctx) as c:
        for k in range(5):
            cam = Camera.look_at(eye + 0.02 * k * d, eye + (10 + 0.02 * k) * d, up=(0, 0, 1),
                                 fov_y_deg=60, aspect=1.5, near=0.1, far=1000)
            truth = c.truth(cam)
            r = c.cull(cam)
            assert not (truth & ~r.visible).any()
            assert culled(r) > 0
            if k:
                assert r.stats.fresh == 0 and r.stats.multiple_queries <= 2


@pytest.mark.parametrize("strategy", ["om_coherent", "auto"])
def test_coherent_default_stays_within_its_read_budget(ctx, strategy):
    """om_coherent (and auto through it) make at most COHERENT_READS multiple
    queries a pass, fresh or not, and still keep every visible object."""
    from core.cull.occupancy_queries import COHERENT_READS
    for seed in (3, 7, 11):
        scene, cams, _ = scenes.random_city(seed, 400)
        with Culler(scene, (160, 120), strategy=strategy, ctx=ctx) as c:
            for cam in cams:
                truth = c.truth(cam)
                for _ in range(2):
                    r = c.cull(cam)
                    assert r.stats.multiple_queries <= COHERENT_READS
                    assert not (truth & ~r.visible).any()
                    # the 4.1 path reads once per box; auto also times a round trip
                    # on its first pass and whenever the clock makes it probe again
                    if getattr(c.renderer, "path", None) == "4.3":
                        timing = Auto.ROUND_TRIPS if strategy == "auto" else 0
                        assert r.stats.blocking_reads <= COHERENT_READS + timing


# A group (a Blender collection) holding one box in front of a wall and two behind it;
# the wall a root of its own.  Front to back, the group opens before the wall is drawn.
GROUPED = [((0.0, -6.0, -2.0), (0.5, 6.0, 6.0)),          # wall
           ((-3.0, -2.0, 0.0), (-2.0, -1.0, 1.0)),        # in front, in the group
           ((3.0, -1.0, 0.0), (4.0, 1.0, 1.0)),           # behind, in the group
           ((3.0, 2.0, 0.0), (4.0, 3.0, 1.0))]            # behind, in the group


@pytest.mark.parametrize("name", [n for n in STRATEGIES if n != "vfc"])
@pytest.mark.parametrize("grouped", [False, True])
def test_a_group_that_opens_before_the_wall_still_culls_behind_it(ctx, name, grouped):
    """Every occlusion strategy culls the two boxes behind the wall, whether or not a
    group holds them with one in front: a node judged on a map that lacked an opened
    group's contents once went to a query, and the map then lacked the wall, so the
    boxes behind it were drawn unqueried (om_multi, om_coherent, two_pass, gpu)."""
    tree = (np.array([-1, -1, 1, 1, 1]), np.array([0, -1, 1, 2, 3])) if grouped else None
    scene = scenes.boxes_scene(GROUPED, tree=tree)
    camera = scenes.cam((-10.0, 0.0, 1.0), (0.0, 0.0, 1.0), fov_y_deg=23.0, aspect=16 / 9)
    with Culler(scene, (160, 90), strategy=name, ctx=ctx) as c:
        truth = c.truth(camera)
        state = c.cull(camera).state
    assert truth.tolist() == [True, True, False, False]
    assert state.tolist() == [Visibility.VISIBLE, Visibility.VISIBLE, Visibility.OCCLUDED, Visibility.OCCLUDED]
