"""A clipping region (a 3D view's Alt+B box): the view draws only what lies inside its
planes, so a wall it cuts hides nothing behind its cut.  An object not wholly inside is
kept visible and never drawn as an occluder; what lies wholly inside culls as before."""

import numpy as np
import pytest

from core import Culler, OccError, Visibility
from core.cull import STRATEGIES
from tests import scenes

CAM = scenes.cam((0.0, -12.0, 0.0), (0.0, 5.0, 0.0), near=0.1, far=100.0, fov_y_deg=50.0)


def wall_and_box():
    """A wall at y = 0 and a box behind it, a second box behind the box."""
    return scenes.boxes_scene([((-6, -0.1, -6), (6, 0.1, 6)), ((-1, 4, -1), (1, 6, 1)),
                               ((-0.5, 8, -0.5), (0.5, 9, 0.5))], ["wall", "box", "far_box"])


def region(lo, hi):
    """The six planes of the axis-aligned box ``[lo, hi]``, inside positive."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    planes = []
    for axis in range(3):
        n = np.zeros(3)
        n[axis] = 1.0
        planes += [[*n, -lo[axis]], [*(-n), hi[axis]]]
    return np.array(planes)


@pytest.mark.parametrize("strategy", ["om_multi", "gpu", "om_coherent"])
def test_a_wall_the_region_cuts_hides_nothing(ctx, strategy):
    scene = wall_and_box()
    with Culler(scene, (64, 48), strategy=strategy, ctx=ctx) as c:
        assert c.cull(CAM).state[1] == Visibility.OCCLUDED                  # sanity: the wall hides the box
        # the region takes the box and the far box, and the wall's back half only: the
        # box shows, and still hides the far box behind it
        r = c.cull(CAM, clip=region((-10, 0.0, -10), (10, 20, 10)))
        assert r.state.tolist() == [Visibility.VISIBLE, Visibility.VISIBLE, Visibility.OCCLUDED]
        assert r.stats.clipped_objects == 1 and r.stats.invalid_objects == 0
        # a region that leaves the box out: the far box shows
        r = c.cull(CAM, clip=region((-10, 7.0, -10), (10, 20, 10)))
        assert r.state.tolist() == [Visibility.VISIBLE] * 3
        assert r.stats.clipped_objects == 2
        # a region that holds everything changes nothing, and the next pass without one culls again
        assert c.cull(CAM, clip=region((-50, -50, -50), (50, 50, 50))).state[1] == Visibility.OCCLUDED
        assert c.cull(CAM).state[1] == Visibility.OCCLUDED
        assert not c.scene.invalid.any()


def test_the_envelope_and_lights_leave_cut_objects_out_too(ctx):
    scene = wall_and_box()
    with Culler(scene, (64, 48), ctx=ctx) as c:
        assert c.cull(CAM, envelope=(0.1, 1.0)).state[1] == Visibility.OCCLUDED
        r = c.cull(CAM, envelope=(0.1, 1.0), clip=region((-10, 0.0, -10), (10, 20, 10)))
        assert r.state[:2].tolist() == [Visibility.VISIBLE] * 2


def test_planes_with_no_normal_are_none_and_nan_planes_refused(ctx):
    with Culler(wall_and_box(), (64, 48), ctx=ctx) as c:
        assert c.clipped(np.zeros((6, 4))) is None         # Alt+B in an ortho view leaves two rows empty
        assert c.clipped(None) is None
        with pytest.raises(OccError, match="NaN"):
            c.cull(CAM, clip=[[np.nan, 0, 0, 0]])
        assert not c.scene.invalid.any()


def _inside_truth(c, scene, cut):
    """The object-ID truth with only the objects wholly inside drawn: which of them the
    camera sees then (a superset of what the clipped view shows of them, where the cut
    objects' parts inside stand in front too; the cut objects are kept anyway)."""
    c._left_out(cut)
    try:
        return c.truth(CAM_CITY)
    finally:
        c._left_out(np.zeros(len(scene), dtype=bool))


CAM_CITY = scenes.cam((-62.0, 0.0, 8.0), (0.0, 0.0, 1.0), near=0.1, far=400.0, fov_y_deg=70.0)


@pytest.mark.parametrize("seed", range(4))
def test_seeded_regions_never_hide_what_the_inside_objects_leave_open(ctx, seed):
    """Random regions over a random city: every object the region cuts stays, every
    hidden object is hidden by the inside objects alone (an exact truth), and the
    region still leaves something to cull."""
    scene, _, _ = scenes.random_city(seed, n=300)
    rng = np.random.default_rng(seed)
    culled = 0
    strategies = [s for s in STRATEGIES if s not in ("oracle", "vfc", "auto")]
    with Culler(scene, (160, 90), strategy=strategies[seed % len(strategies)], ctx=ctx) as c:
        for _ in range(3):
            lo = rng.uniform([-70, -70, -1], [-20, -40, 0])
            hi = rng.uniform([10, 20, 3], [70, 70, 15])
            planes = region(lo, hi)
            if rng.random() < 0.5:                        # a slanted cut as well
                n = rng.normal(size=3)
                n /= np.linalg.norm(n)
                planes = np.vstack([planes, [*n, 40.0]])
            cut = c.clipped(planes)
            r = c.cull(CAM_CITY, clip=planes)
            assert (r.state[cut] == Visibility.VISIBLE).all()
            seen = _inside_truth(c, scene, cut)
            wrong = np.flatnonzero((r.state == Visibility.OCCLUDED) & seen)
            assert not len(wrong), f"hid {wrong} which the inside objects leave open"
            culled += int((r.state == Visibility.OCCLUDED).sum())
            assert not c.scene.invalid.any()
    assert culled > 0
