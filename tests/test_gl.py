"""GL backend on tiny targets with exact, analytic expectations."""

import numpy as np
import pytest

from core import Camera, Culler, OccError, Scene
from core.gl import GLRenderer
from tests.scenes import boxes_scene


def ortho_cam(offset=(0.0, 0.0, 0.0), w=8, h=8):
    """Looking down -Z onto the XY plane; one pixel = one unit; pixel (i, j) centre
    at world (i + 0.5 - w/2, j + 0.5 - h/2)."""
    off = np.asarray(offset)
    return Camera.look_at(off + (0, 0, 10), off, up=(0, 1, 0), aspect=w / h, near=1, far=20,
                          ortho_height=h)


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (1e6, 1e6, -1e6), (3e7, 0.0, 0.0)])
def test_id_buffer_exact(ctx, offset):
    """Two boxes on an 8x8 target cover exactly the pixel centres inside them."""
    # edges between pixel centres, so no tie-breaking rule is involved
    scene = boxes_scene([((-4, -4, 0), (-1.2, 0.2, 1)), ((0.2, 0.2, 2), (2.2, 3.2, 3))],
                        offset=offset)
    r = GLRenderer(scene, 8, 8, ctx=ctx)
    ids = r.object_ids(ortho_cam(offset))
    expect = np.full((8, 8), -1)
    expect[0:4, 0:3] = 0          # x centres -3.5..-1.5, y centres -3.5..-0.5 (row 0 at the bottom)
    expect[4:7, 4:6] = 1          # x centres 0.5, 1.5; y centres 0.5..2.5; nearer, so it wins
    assert np.array_equal(ids, expect), ids[::-1]
    r.release()


def test_queries_count_exact_samples(ctx):
    scene = boxes_scene([((-4, -4, 0), (0, 4, 1))])          # covers the left half
    r = GLRenderer(scene, 8, 8, ctx=ctx)
    cam = ortho_cam()
    r.begin_frame(cam)
    r.draw([0])
    eye = cam.eye
    probes = np.array([((-3, -3, 3), (3, 3, 4)),          # in front: 6x6 = 36 pixels
                       ((-3, -3, -3), (3, 3, -2)),        # behind: only the right half, 3x6
                       ((-2, -2, -5), (-1, -1, -4)),      # fully behind the drawn box
                       ((-3, -3, 0.5), (-1, -1, 3))])     # front face in front, back face behind
    samples = r.query(probes - eye)
    # front faces only (one sample per covered pixel centre), so winding is right
    assert samples.tolist() == [36, 18, 0, 4]
    r.release()


@pytest.mark.parametrize("strategy", ["stopwait", "om", "om_multi"])
def test_coplanar_ties_count_as_visible(ctx, strategy):
    """A flat object lying exactly on another's top face is kept: the engine grows
    query boxes by a relative guard and tests them with <=, so ties are visible."""
    scene = boxes_scene([((-4, -4, 0), (4, 4, 1)), ((-2, -2, 1), (2, 2, 1)),
                         ((-1, -1, 0.2), (1, 1, 0.8))], ["base", "decal", "inside"])
    with Culler(scene, (8, 8), strategy=strategy, ctx=ctx) as c:
        r = c.cull(ortho_cam())
    assert r.state.tolist() == [0, 0, 1]       # base, decal visible; inside occluded


def test_shared_mesh_is_uploaded_once(ctx):
    scene = boxes_scene([((i, 0, 0), (i + 0.5, 1, 1)) for i in range(100)])
    assert len(scene.meshes) == 1
    r = GLRenderer(scene, 4, 4, ctx=ctx)
    assert r.vbo.size == 8 * 12 and r.ibo.size == 36 * 4
    r.release()


def test_zero_size_resolution_is_a_clear_error(ctx):
    scene = boxes_scene([((0, 0, 0), (1, 1, 1))])
    with pytest.raises(OccError, match="resolution"):
        Culler(scene, (0, 10), ctx=ctx)


def test_empty_scene_gives_empty_answer(ctx):
    scene = Scene.from_arrays([], [], np.zeros(0, int), np.zeros((0, 4, 4)))
    with Culler(scene, (16, 16), ctx=ctx) as c:
        r = c.cull(ortho_cam())
        assert r.state.shape == (0,) and r.stats.objects == 0
        assert c.truth(ortho_cam()).shape == (0,)


def test_one_object_and_all_behind_camera(ctx):
    one = boxes_scene([((-1, -1, 0), (1, 1, 1))])
    with Culler(one, (16, 16), ctx=ctx) as c:
        assert c.cull(ortho_cam()).visible.tolist() == [True]
    behind = boxes_scene([((-1, -1, 30), (1, 1, 31)), ((5, 5, 40), (6, 6, 41))])
    with Culler(behind, (16, 16), ctx=ctx) as c:
        r = c.cull(ortho_cam())
        assert r.state.tolist() == [2, 2] and r.stats.queries == 0
        assert not c.truth(ortho_cam()).any()


def test_nan_matrix_in_scene_is_named_not_fatal():
    """One bad object names itself and fails nothing else (the engine keeps it
    visible; see tests/test_conservative_answers.py)."""
    m = np.eye(4)[None].copy()
    m[0, 1, 3] = np.inf
    s = Scene.from_arrays(["bad"], [(np.zeros((3, 3)), [[0, 1, 2]])], [0], m)
    assert s.invalid_names == ["bad"]


def test_two_renderers_alive_at_once_each_use_their_own_context():
    """Each Culler owns an EGL context; interleaved passes must not draw into the other's."""
    a_scene = boxes_scene([((-4, -4, 0), (4, 4, 1)), ((-1, -1, -3), (1, 1, -2))])
    b_scene = boxes_scene([((-1, -1, -3), (1, 1, -2))])
    with Culler(a_scene, (16, 16), strategy="om_multi") as a:
        with Culler(b_scene, (16, 16), strategy="om_multi") as b:
            for _ in range(2):
                assert a.cull(ortho_cam()).state.tolist() == [0, 1]
                assert b.cull(ortho_cam()).state.tolist() == [0]
                assert a.truth(ortho_cam()).tolist() == [True, False]


def test_a_released_context_is_not_kept():
    """A renderer that made its own context keeps nothing of it once released: the
    per-context GL state (a weak-keyed map whose value held a framebuffer of the
    context) kept every context a process made, one more per engine rebuild."""
    import gc
    import weakref

    from core.gl import renderer

    scene = boxes_scene([((-1, -1, -3), (1, 1, -2))])
    before = len(renderer._CONTEXT_STATE)
    kept = []
    for _ in range(3):
        with Culler(scene, (8, 8), strategy="om_multi", display=(16, 16)) as c:
            c.cull(ortho_cam())
            c.truth(ortho_cam())
            kept.append(weakref.ref(c.renderer.ctx))
        del c
    gc.collect()
    assert len(renderer._CONTEXT_STATE) == before
    assert all(k() is None for k in kept)
