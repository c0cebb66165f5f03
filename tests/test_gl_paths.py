"""The two GL paths (4.3 one-draw queries, 4.1 query objects), their counters, pending
batches, mirrored cameras and the conservative display -> query depth reduction.

Tiny targets with analytic expectations; every test that takes ``ctx`` is bracketed
by a GL-error check (tests/conftest.py).
"""

import sys
from types import SimpleNamespace

import numpy as np
import pytest

from core import Camera, Culler, OccError
from core.gl import GLRenderer
from core.gl.context import choose_path
from tests.scenes import HOLE_SCENE, boxes_scene, ortho_cam

PATHS = ["4.3", "4.1"]


PROBES = np.array([((-3, -3, 3), (3, 3, 4)),          # in front: 6x6 = 36 pixels
                   ((-3, -3, -3), (3, 3, -2)),        # behind: only the uncovered half, 3x6
                   ((-2, -2, -5), (-1, -1, -4)),      # fully behind the drawn box
                   ((-3, -3, 0.5), (-1, -1, 3))])     # front face in front, back face behind


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("mirror", [False, True])
def test_query_samples_exact_on_both_paths_and_mirrored(ctx, path, mirror):
    """Front faces only, one sample per covered pixel centre; a mirrored camera flips
    the winding, and the front faces are still the ones drawn (the last probe, whose
    back face is hidden, would read 0 with the back faces)."""
    scene = boxes_scene([((-4, -4, 0), (0, 4, 1))])          # covers the left half
    r = GLRenderer(scene, 8, 8, ctx=ctx, path=path)
    assert r.path == path
    cam = ortho_cam(mirror=mirror)
    r.begin_frame(cam)
    r.draw([0])
    assert r.query(PROBES - cam.eye).tolist() == [36, 18, 0, 4]
    r.release()


@pytest.mark.parametrize("path", PATHS)
def test_mirrored_camera_object_seen_through_a_hole(ctx, path):
    """A post seen through a hole, its foot in a back wall: only its query box's front
    faces are in front of the depth there.  Under a mirrored camera (x scale -1) the
    winding flips; the post must still pass (4 = the 2x2 pixel centres of the hole)."""
    scene = boxes_scene(HOLE_SCENE)
    r = GLRenderer(scene, 8, 8, ctx=ctx, path=path)
    for mirror in (False, True):
        cam = ortho_cam(mirror=mirror)
        r.begin_frame(cam)
        r.draw([0, 1, 2, 3, 5])
        assert r.query(scene.bounds[[4, 6]] - cam.eye).tolist() == [4, 0], mirror
    r.release()


@pytest.mark.parametrize("strategy", ["stopwait", "om", "om_multi", "om_coherent"])
def test_mirrored_camera_culls_as_the_unmirrored_one(ctx, strategy):
    """The whole engine (frustum planes, rectangles, queries) under a mirrored camera."""
    scene = boxes_scene(HOLE_SCENE)
    states = []
    for mirror in (False, True):
        with Culler(scene, (8, 8), strategy=strategy, ctx=ctx) as c:
            states.append(c.cull(ortho_cam(mirror=mirror)).state.tolist())
            assert c.truth(ortho_cam(mirror=mirror)).tolist() == [True] * 5 + [False, False]
    assert states[0] == states[1]
    assert states[1][:5] == [0] * 5 and states[1][6] == 1        # the post visible, the hidden one culled


def random_scene(seed, n=60):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-10, 10, (n, 3)) * (1, 1, 0.5)
    hi = lo + rng.uniform(0.2, 4.0, (n, 3))
    return boxes_scene(list(zip(lo, hi, strict=True)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_both_paths_give_identical_samples_on_a_random_scene(ctx, seed):
    """Seeded random boxes, random draw orders and random query boxes from three
    perspective cameras: every sample count equal on 4.3 and 4.1."""
    scene = random_scene(seed)
    rng = np.random.default_rng(100 + seed)
    renderers = {p: GLRenderer(scene, 37, 23, ctx=ctx, path=p) for p in PATHS}
    for _ in range(3):
        eye = rng.uniform(-20, 20, 3) + (0, 0, 25)
        cam = Camera.look_at(eye, rng.uniform(-3, 3, 3), fov_y_deg=70, aspect=37 / 23, near=0.5, far=100)
        order = rng.permutation(len(scene))
        probes = np.sort(rng.uniform(-12, 12, (40, 2, 3)), axis=1) - cam.eye
        out = {}
        for p, r in renderers.items():
            r.begin_frame(cam)
            first = r.query(probes)
            r.draw(order[:30])
            second = r.query(probes)
            r.draw(order[30:])
            flags = r.query(probes, counts=False)
            out[p] = (first, second, r.query(probes), flags, r.read_depth().copy(), r.object_ids(cam))
            assert np.array_equal(flags, np.minimum(out[p][2], 1))       # flags: 1 where any sample passed
        for a, b in zip(out["4.3"], out["4.1"], strict=True):
            assert np.array_equal(a, b)
        assert out["4.3"][1].sum() > out["4.3"][2].sum() > 0      # the draws occluded something
    for r in renderers.values():
        r.release()


@pytest.mark.parametrize("strategy", ["stopwait", "om", "om_multi", "om_coherent"])
def test_both_paths_give_identical_culling(ctx, strategy, monkeypatch):
    """The engine on OCC_GL=4.1 and on 4.3: the same states and counts of queries."""
    scene = random_scene(7, 80)
    cams = [Camera.look_at((x, -25, 12), (0, 0, 0), aspect=1.5, near=0.5, far=100) for x in (-8, 0, 8)]
    runs = {}
    for p in PATHS:
        monkeypatch.setenv("OCC_GL", p)
        with Culler(scene, (48, 32), strategy=strategy, ctx=ctx) as c:
            assert c.renderer.path == p
            runs[p] = [(c.cull(cam).state.tolist(), c.cull(cam).stats.queries) for cam in cams]
    assert runs["4.3"] == runs["4.1"]


def test_query_slots_stay_one_per_batch_in_flight(ctx):
    """4.3: the renderer is made with one query slot; a batch larger than every free
    slot grows one in place (the same buffer and vertex arrays), a smaller one is served
    by the smallest free slot that holds it, reading exactly its own counters.  A new
    slot only for a batch issued while every slot holds a pending one, so the GL objects
    alive stay the same over a long session whatever the batch sizes."""
    scene = random_scene(4)
    rng = np.random.default_rng(4)
    r = GLRenderer(scene, 37, 23, ctx=ctx, path="4.3")
    cam = Camera.look_at((0, -25, 12), (0, 0, 0), fov_y_deg=70, aspect=37 / 23, near=0.5, far=100)
    r.begin_frame(cam)
    r.draw(np.arange(30))
    first = list(r.slots)
    glo = [(s.buffer.glo, {k: v.glo for k, v in s.vaos.items()}) for s in first]
    probes = np.sort(rng.uniform(-12, 12, (1500, 2, 3)), axis=1) - cam.eye
    one = np.concatenate([r.query(probes[i:i + 1]) for i in range(len(probes))])  # one box a batch
    assert one.sum() > 0
    for k in (600, 3, 1500, 170, 400, 1, 70, 1300, 600):    # grown twice, in place
        assert np.array_equal(r.query(probes[:k]), one[:k]), k
    assert r.slots == first and r.slots[0].cap >= 1500
    assert [(s.buffer.glo, {k: v.glo for k, v in s.vaos.items()}) for s in r.slots] == glo
    sizes = (90, 2, 1500)
    pending = [(k, r.query_async(probes[-k:])) for k in sizes]      # pending at once: a slot each
    for k, q in reversed(pending):
        assert np.array_equal(q.result(), one[-k:]), k
    assert len(r.slots) == len(sizes)
    pending = [(k, r.query_async(probes[-k:])) for k in sizes[::-1]]
    for k, q in pending:
        assert np.array_equal(q.result(), one[-k:]), k
    assert len(r.slots) == len(sizes)
    r.release()


@pytest.mark.parametrize("path", PATHS)
def test_pending_batch_keeps_its_answer_across_later_draws(ctx, path):
    """Batch A is issued, an occluder is drawn, batch B is issued; A still reads the
    depth as it was when A was issued, B sees the occluder."""
    scene = boxes_scene([((-4, -4, 5), (4, 4, 6))])            # covers everything, near
    r = GLRenderer(scene, 8, 8, ctx=ctx, path=path)
    cam = ortho_cam()
    r.begin_frame(cam)
    probe = np.array([((-1, -1, 0), (1, 1, 1))]) - cam.eye     # 2x2 pixels
    a = r.query_async(probe)
    r.draw([0])
    b = r.query_async(probe)
    c = r.query_async(probe)
    assert b.result().tolist() == [0]
    assert a.result().tolist() == [4]
    assert a.result().tolist() == [4] and c.result().tolist() == [0]     # result() is idempotent
    assert r.query(np.zeros((0, 2, 3))).shape == (0,)
    r.release()


@pytest.mark.parametrize("path", PATHS)
def test_counters_per_frame(ctx, path):
    """4.3: a batch of any size is one draw and one blocking read; 4.1: one per box.
    begin_frame does the same GL work for 1 object as for 300 (no per-object pass)."""
    boxes = [((i % 20 - 10, i // 20 - 8, 0), (i % 20 - 9.5, i // 20 - 7.5, 1)) for i in range(300)]
    calls = []
    for scene in (boxes_scene(boxes[:1]), boxes_scene(boxes)):
        r = GLRenderer(scene, 8, 8, ctx=ctx, path=path)
        r.begin_frame(ortho_cam())
        calls.append(dict(r.counters))
        r.release()
    assert calls[0] == calls[1] and calls[0]["draws"] == 0
    r = GLRenderer(boxes_scene(boxes[:1]), 8, 8, ctx=ctx, path=path)
    cam = ortho_cam()
    r.begin_frame(cam)
    r.draw([0])
    k = 50
    probes = np.repeat(np.array([((-3, -3, 3), (3, 3, 4))]), k, axis=0) - cam.eye
    samples = r.query(probes)
    c = r.counters
    assert c["query_batches"] == 1 and c["query_fragments"] == samples.sum() == 36 * k
    if path == "4.3":
        assert c["draws"] == 2 and c["blocking_reads"] == 1
    else:
        assert c["draws"] == 1 + k and c["blocking_reads"] == k
    assert c["gl_calls"] > c["draws"] + c["blocking_reads"]
    assert r.query(probes, counts=False).tolist() == [1] * k
    assert r.counters["query_fragments"] == 36 * k                   # flags count no fragments
    r.begin_frame(cam)
    assert r.counters["draws"] == r.counters["blocking_reads"] == 0
    r.release()


def test_path_choice_and_errors(ctx, monkeypatch):
    monkeypatch.delenv("OCC_GL", raising=False)
    assert choose_path(ctx) == ("4.3" if ctx.version_code >= 430 else "4.1")
    assert choose_path(ctx, "4.1") == "4.1"
    monkeypatch.setenv("OCC_GL", "4.1")
    assert choose_path(ctx) == "4.1"
    monkeypatch.setenv("OCC_GL", "3.3")
    with pytest.raises(OccError, match="OCC_GL must be one of 4.3, 4.1"):
        choose_path(ctx)
    old = SimpleNamespace(version_code=410)                   # what a Mac's context reports
    monkeypatch.delenv("OCC_GL")
    assert choose_path(old) == "4.1"
    with pytest.raises(OccError, match="needs a 4.3 context, this one is 4.1"):
        choose_path(old, "4.3")


# --- conservative query resolution below the display's -----------------------------

DEPTH_STEP = 1.0 / (2**24 - 1)


def assert_reduced(got, expect):
    """The reduction's value: the farthest display depth plus at most 3 steps of the
    24-bit depth buffer (one added on purpose, rounding), never nearer."""
    steps = (got.astype(np.float64) - expect) / DEPTH_STEP
    assert steps.min() >= -1e-3 and steps.max() <= 3.001, (steps.min(), steps.max())
    assert np.array_equal(got == 1.0, expect == 1.0)

def gap_scene(gap_at):
    """A thick wall over the whole 8x8 view (one unit per display pixel) with a slot
    half a display pixel wide around the centre of display column ``gap_at``, so no
    query pixel centre (odd coordinates at 4x4) sees through it; a post at z=0 behind
    the slot, and one behind solid wall."""
    x0 = gap_at - 4                                       # display column gap_at spans x0..x0+1
    return boxes_scene([((-4, -4, 2), (x0 + 0.25, 4, 6)), ((x0 + 0.75, -4, 2), (4, 4, 6)),
                        ((x0 + 0.4, -1, 0), (x0 + 0.6, 1, 1)),        # post seen through the slot
                        ((-4, -4, -1), (-3, -3, 0))])                 # hidden post


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("gap_at", [2, 5])
def test_display_gap_stays_open_at_query_resolution(ctx, path, gap_at):
    """Display 8x8, query 4x4: a slot one display pixel wide.  Drawn at 4x4 directly the
    slot falls between query pixel centres and the post behind it reads 0 samples;
    with the reduction (farthest depth of the display pixels a query pixel covers)
    its query pixel column is open and the post is visible.  The post behind solid
    wall stays hidden either way."""
    scene = gap_scene(gap_at)
    cam = ortho_cam()
    post, hidden = scene_boxes(scene)[2:] - cam.eye
    # The caller's guard: at least 0.71 query pixel (1.41 units) on every side.
    grow = np.array([[-1.5, -1.5, -1.5], [1.5, 1.5, 1.5]])
    probes = np.array([post + grow, hidden + (0.1 * grow)])
    plain = GLRenderer(scene, 4, 4, ctx=ctx, path=path)
    plain.begin_frame(cam)
    plain.draw([0, 1])
    assert plain.query(probes).tolist() == [0, 0]              # the gap closed: wrongly hidden
    plain.release()
    r = GLRenderer(scene, 4, 4, ctx=ctx, path=path, display=(8, 8))
    r.begin_frame(cam)
    r.draw([0, 1])
    assert r.display == (8, 8) and r.read_depth(display=True).shape == (8, 8)
    samples = r.query(probes)
    assert samples[0] == 2 and samples[1] == 0, samples        # one query column, 2 rows
    # the reduced depth is the 2x2 max of the display depth, never nearer
    d = r.read_depth(display=True)
    assert_reduced(r.read_depth(), d.reshape(4, 2, 4, 2).max(axis=(1, 3)))
    assert r.visible_truth(cam, display=True).tolist() == [True, True, True, False]
    r.release()


def scene_boxes(scene):
    return scene.bounds


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("display, query", [((10, 7), (4, 3)),      # ratios 2.5, 2.33: the loop
                                            ((8, 6), (4, 3)),       # 2x2: one textureGather
                                            ((16, 12), (4, 3))])    # 4x4: four gathers
def test_reduction_takes_every_overlapped_display_pixel(ctx, path, display, query):
    """Each query pixel holds the max of the display pixels its area overlaps, by a
    numpy reference, for fractional and even ratios."""
    (dw, dh), (w, h) = display, query
    rng = np.random.default_rng(5)
    lo = rng.uniform(-5, 4, (25, 3)) * (1, 0.7, 1) + (0, 0, 4)
    scene = boxes_scene(list(zip(lo, lo + rng.uniform(0.3, 2.5, (25, 3)), strict=True)))
    cam = Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0), aspect=dw / dh, near=1, far=20,
                         ortho_height=7)
    r = GLRenderer(scene, w, h, ctx=ctx, path=path, display=display)
    r.begin_frame(cam)
    r.draw(np.arange(len(scene)))
    d = r.read_depth(display=True)
    expect = np.zeros((h, w), np.float32)
    for j in range(h):
        for i in range(w):
            y0, y1 = (j * dh) // h, -(-((j + 1) * dh) // h)
            x0, x1 = (i * dw) // w, -(-((i + 1) * dw) // w)
            expect[j, i] = d[y0:y1, x0:x1].max()
    assert len(np.unique(d)) > 3                               # the picture has structure
    assert_reduced(r.read_depth(), expect)
    r.release()


@pytest.mark.parametrize("path", PATHS)
def test_reduction_only_where_drawn_is_complete(ctx, path):
    """Draws in several batches with queries in between (each reduces only the
    rectangle drawn since the last): the final query depth equals one full reduction."""
    scene = random_scene(11, 40)
    cam = Camera.look_at((3, -20, 15), (0, 0, 0), aspect=1.5, near=0.5, far=100)
    r = GLRenderer(scene, 24, 16, ctx=ctx, path=path, display=(48, 32))
    r.begin_frame(cam)
    probe = np.array([((-20, -20, -20), (20, 20, 20))]) + (0, 0, -200.0)
    for part in np.array_split(np.random.default_rng(0).permutation(len(scene)), 5):
        r.draw(part)
        r.query(probe)
    d = r.read_depth(display=True)
    assert (d < 1).mean() > 0.1
    assert_reduced(r.read_depth(), d.reshape(16, 2, 24, 2).max(axis=(1, 3)))
    r.release()


def test_display_smaller_than_query_is_an_error(ctx):
    with pytest.raises(OccError, match="display resolution 4x8 must be at least the query resolution 8x8"):
        GLRenderer(boxes_scene([((0, 0, 0), (1, 1, 1))]), 8, 8, ctx=ctx, display=(4, 8))


@pytest.mark.parametrize("path", PATHS)
def test_renderers_sharing_a_context_interleave(ctx, path):
    """Two renderers on one context, their calls interleaved without a new frame in
    between (the state each sets is tracked per context, not per renderer)."""
    wall = GLRenderer(boxes_scene([((-4, -4, 2), (4, 4, 3))]), 8, 8, ctx=ctx, path=path)
    empty = GLRenderer(boxes_scene([((-4, -4, -9), (-3, -3, -8))]), 8, 8, ctx=ctx, path=path,
                       display=(16, 16))
    cam = ortho_cam()
    probe = np.array([((-1, -1, 0), (1, 1, 1))]) - cam.eye
    wall.begin_frame(cam)
    empty.begin_frame(cam)
    wall.draw([0])
    empty.draw([0])
    for _ in range(2):
        assert wall.query(probe).tolist() == [0]
        assert empty.query(probe).tolist() == [4]
    wall.release()
    empty.release()


def test_many_small_draws_wrap_the_stream(ctx):
    """4.3: per-draw commands and matrices go into a ring buffer (the stream); more draws
    than it holds orphan it and start again at 0, and one draw bigger than it grows it.
    The depth and IDs stay those of one draw of everything."""
    scene = random_scene(4, 30)
    cam = Camera.look_at((3, -20, 15), (0, 0, 0), aspect=1.5, near=0.5, far=100)
    r = GLRenderer(scene, 24, 16, ctx=ctx, path="4.3")
    r.begin_frame(cam)
    r.draw(np.arange(len(scene)))
    expect = r.read_depth().copy()
    r.begin_frame(cam)
    size = r.stream_size
    for _ in range(4):                               # 120 draws of one unit: past the stream's end
        for u in range(len(scene)):
            r.draw([u])
    # two calls a draw, one for the frame's clear, and about one orphan per 11 draws
    assert r.counters["gl_calls"] >= 2 * 120 + 1 + 8
    assert np.array_equal(r.read_depth(), expect)
    r.begin_frame(cam)
    r.draw(np.tile(np.arange(len(scene)), 200))      # 6,000 units in one draw: a bigger stream
    assert r.stream_size > size
    assert np.array_equal(r.read_depth(), expect)
    other = GLRenderer(scene, 24, 16, ctx=ctx, path="4.1")
    assert np.array_equal(r.object_ids(cam), other.object_ids(cam))
    other.release()
    r.release()


@pytest.mark.parametrize("path", PATHS)
def test_unread_batches_give_their_resources_back(ctx, path):
    """A pending batch dropped unread returns its buffer (4.3) or query objects (4.1)."""
    r = GLRenderer(boxes_scene([((-4, -4, 0), (0, 4, 1))]), 8, 8, ctx=ctx, path=path)
    cam = ortho_cam()
    r.begin_frame(cam)
    r.draw([0])
    for _ in range(20):
        r.query_async(PROBES - cam.eye)                       # dropped at once
    assert r.query(PROBES - cam.eye).tolist() == [36, 18, 0, 4]
    held = len(r.slots) if path == "4.3" else len(r.free_queries)
    assert held == (1 if path == "4.3" else len(PROBES))
    r.release()


@pytest.mark.parametrize("platform, says", [
    ("linux", "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri"),
    ("darwin", "OpenGL 4.1 core, which every Mac since 2012 has"),
    ("win32", "update the GPU driver")])
def test_no_context_error_says_what_to_do_per_platform(platform, says, monkeypatch):
    from core.gl import context
    monkeypatch.setattr(context.sys, "platform", platform)
    assert says in context.platform_hint()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="EGL is the Linux backend")
def test_missing_libegl_error_lists_each_version_tried(monkeypatch):
    """Linux without a loadable libEGL: both versions were tried, each failure named."""
    from core.gl import create_context
    monkeypatch.setenv("OCC_LIBEGL", "libEGL-missing.so.1")
    monkeypatch.delenv("OCC_GL", raising=False)
    with pytest.raises(OccError, match=r"OpenGL 4\.3: .*; OpenGL 4\.1: .*apt-get install libegl1"):
        create_context()


@pytest.mark.parametrize("path", PATHS)
def test_huge_and_infinite_boxes_keep_their_samples(ctx, path):
    """A box reaching 1e300 or infinity (beyond float32) answers as one just larger than
    the view: its part inside the frustum is all that is drawn."""
    scene = boxes_scene([((-4, -4, 0), (0, 4, 1))])          # covers the left half
    r = GLRenderer(scene, 8, 8, ctx=ctx, path=path)
    cam = ortho_cam()
    r.begin_frame(cam)
    r.draw([0])
    big = np.array([((-20, -20, 3), (20, 20, 4)), ((-20, -20, -3), (20, 20, -2)),
                    ((-1e300, -1e300, 3), (1e300, 1e300, 4)), ((-np.inf, -np.inf, -3), (np.inf, np.inf, -2))])
    with np.errstate(over="raise"):
        assert r.query(big - cam.eye).tolist() == [64, 32, 64, 32]
    r.release()


class _Attached:
    def __init__(self, renderer):
        self.renderer, self.released = renderer, 0

    def release(self):
        self.released += 1


@pytest.mark.parametrize("path", PATHS)
def test_each_path_is_a_renderer_and_keeps_its_attachments(ctx, path):
    """Both paths implement the Renderer interface; an attachment is made once per key
    (nothing kept when its factory raises) and released with the renderer."""
    from core.gl import Renderer
    r = GLRenderer(boxes_scene([((-4, -4, 0), (0, 4, 1))]), 8, 8, ctx=ctx, path=path)
    assert isinstance(r, Renderer) and r.path == path
    a = r.attachment("probe", _Attached)
    assert r.attachment("probe", _Attached) is a and a.renderer is r

    def refuse(_renderer):
        raise RuntimeError("no")
    with pytest.raises(RuntimeError):
        r.attachment("other", refuse)
    assert r.attachment("other", _Attached) is not a
    r.release()
    assert a.released == 1
