"""Render sizes (issue 30): a seeded sweep of the engine over wide, tall, tiny and odd
render sizes, a render size that changes between passes, every strategy and both
presets at the query resolution the add-on picks for them (its largest query side
1920, and 16: a query resolution whose scale to the display differs per axis):
no object that the object-ID truth sees at the display (render) resolution is culled.

The cameras are Blender's: the projection ``calc_matrix_camera`` gives (its viewplane,
ported below: sensor fit, lens shift, pixel aspect, orthographic), at the render size;
``tests/blender/in_blender/cameras.py::camera_render_sizes`` checks that the add-on
culls with exactly that projection and size in Blender.  The scene is the seeded
workflows' (walls and props), with slits between walls from a tenth of a pixel to a
few pixels wide and props behind them.
"""

import math

import numpy as np
import pytest

from core import Camera, Culler, Scene, Visibility
from core.cull import REGISTRY
from core.settings import MAX_RESOLUTION, PRESETS, preset, query_resolution

BOX_V = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float64) - 0.5
BOX_F = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
# wide, tall, tiny (1 to 8 pixels a side), odd; in this order, a render size that keeps
# changing between passes (the 160x60 -> 200x60 -> 200x66 among them)
SIZES = ((160, 60), (200, 60), (200, 66), (201, 60), (300, 60), (100, 30), (400, 120), (60, 200),
         (97, 13), (13, 97), (333, 2), (256, 1), (1, 256), (64, 3), (3, 64), (50, 8), (8, 50), (7, 1),
         (2, 5), (1, 1), (199, 61))
MAX_QUERY = (1920, 16)              # the add-on's default largest query side, and its smallest


def fit(display, longest):
    """The add-on's ``occ_addon.session.fit``: ``display`` scaled so its longest side is
    at most ``longest`` (occ_addon imports bpy: restated here)."""
    w, h = display
    s = min(1.0, longest / max(w, h))
    return max(1, round(w * s)), max(1, round(h * s))


def sizes(display, preset_name, longest):
    """``(query resolution, display or None)`` as the add-on's ``Session._sizes`` picks them."""
    res = query_resolution(fit(display, longest), preset(preset_name))
    shown = fit(display, MAX_RESOLUTION)
    return res, (shown if shown != res else None)


def blender_projection(winx, winy, aspx=1.0, aspy=1.0, ortho=False, lens=50.0, ortho_scale=7.0,
                       fit="AUTO", shift_x=0.0, shift_y=0.0, clip_start=0.1, clip_end=100.0):
    """``Object.calc_matrix_camera(x=winx, y=winy, scale_x=aspx, scale_y=aspy)`` of a camera
    with these settings (Blender's BKE_camera_params_compute_viewplane and _matrix;
    sensor 36 x 24 mm)."""
    ycor = aspy / aspx
    pixsize = ortho_scale if ortho else (24.0 if fit == "VERTICAL" else 36.0) * clip_start / lens
    if fit == "AUTO":
        fit = "HORIZONTAL" if aspx * winx >= aspy * winy else "VERTICAL"
    viewfac = winx if fit == "HORIZONTAL" else ycor * winy
    pixsize /= viewfac
    x0, x1 = (-0.5 * winx + shift_x * viewfac) * pixsize, (0.5 * winx + shift_x * viewfac) * pixsize
    y0, y1 = (-0.5 * ycor * winy + shift_y * viewfac) * pixsize, (0.5 * ycor * winy + shift_y * viewfac) * pixsize
    n, f = clip_start, clip_end
    p = np.zeros((4, 4))
    p[0, 0], p[1, 1] = 2.0 / (x1 - x0), 2.0 / (y1 - y0)
    if ortho:
        p[0, 3], p[1, 3] = -(x1 + x0) / (x1 - x0), -(y1 + y0) / (y1 - y0)
        p[2, 2], p[2, 3], p[3, 3] = -2.0 / (f - n), -(f + n) / (f - n), 1.0
    else:
        p[0, 0], p[1, 1] = p[0, 0] * n, p[1, 1] * n
        p[0, 2], p[1, 2] = (x1 + x0) / (x1 - x0), (y1 + y0) / (y1 - y0)
        p[2, 2], p[2, 3], p[3, 2] = -(f + n) / (f - n), -2.0 * f * n / (f - n), -1.0
    return p


def _box(centre, scale, turn=0.0):
    c, s = math.cos(turn), math.sin(turn)
    m = np.eye(4)
    m[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.diag(scale)
    m[:3, 3] = centre
    return m


def workflow_scene(rng, slit_px):
    """The seeded workflows' scene (6 walls, 28 props, their collections as the tree) and
    two walls in a row with a slit between them, ``slit_px`` pixels of the camera at
    (-12, 0, 1) looking down +x at 200 pixels across wide (lens 50), props behind it."""
    mats = [_box((rng.uniform(-5, 5), rng.uniform(-5, 5), h / 2 - 0.5), (0.3, rng.uniform(5, 11), h),
                 rng.uniform(0, math.pi)) for h in rng.uniform(2, 4.5, 6)]
    for _ in range(28):
        s = rng.uniform(0.25, 1.0)
        mats.append(_box((rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(0, 1.5)),
                         (s, s * rng.uniform(0.5, 1.5), s), rng.uniform(0, math.pi)))
    gap = slit_px * 12.0 * 0.72 / 200.0               # world width of slit_px pixels 12 units away
    mats += [_box((0.0, -2.0 - gap / 2, 1.0), (0.2, 4.0, 4.0)), _box((0.0, 2.0 + gap / 2, 1.0), (0.2, 4.0, 4.0))]
    mats += [_box((rng.uniform(3, 9), rng.uniform(-0.3, 0.3), rng.uniform(0, 2)), (0.3, 0.3, 0.3)) for _ in range(4)]
    n = len(mats)
    parent = [-1, 0, 0, 2] + [1 if i < 6 or i >= 34 else (3 if (i - 6) % 4 == 0 else 2) for i in range(n)]
    carried = [-1, -1, -1, -1] + list(range(n))
    return Scene.from_arrays([f"o{i}" for i in range(n)], [(BOX_V, BOX_F)], np.zeros(n, int), np.array(mats),
                             np.array(parent), np.array(carried))


def _look(eye, target):
    f = target - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, (0.0, 0.0, 1.0))
    s /= np.linalg.norm(s)
    v = np.eye(4)
    v[0, :3], v[1, :3], v[2, :3] = s, np.cross(s, f), -f
    v[:3, 3] = -v[:3, :3] @ eye
    return v


def cameras(rng, w, h):
    """At the slit (as its pixels were measured), and one as the workflows place and
    set it: around or inside the scene, a random lens, clipping, shift and sensor fit,
    now and then orthographic, now and then non-square pixels."""
    out = [Camera.from_matrices(_look(np.array([-12.0, rng.uniform(-0.02, 0.02), 1.0]), np.array([0.0, 0.0, 1.0])),
                                blender_projection(w, h))]
    a, d = rng.uniform(0, 2 * math.pi), (rng.uniform(11, 17) if rng.random() < 0.5 else rng.uniform(2, 9))
    eye = np.array([d * math.cos(a), d * math.sin(a), rng.uniform(0.5, 5)])
    target = np.array([rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(0, 1)])
    clip = ((0.1, 100.0), (0.5, 14.0), (0.01, 1000.0))[rng.integers(3)]
    aspect = ((1.0, 1.0), (1.0, 1.0), (2.0, 1.0), (1.0, 2.0))[rng.integers(4)]
    proj = blender_projection(w, h, *aspect, ortho=rng.random() < 0.25, lens=rng.uniform(18, 85),
                              ortho_scale=rng.uniform(6, 25), fit=("AUTO", "HORIZONTAL", "VERTICAL")[rng.integers(3)],
                              shift_x=rng.uniform(-0.3, 0.3), shift_y=rng.uniform(-0.2, 0.2),
                              clip_start=clip[0], clip_end=clip[1])
    out.append(Camera.from_matrices(_look(eye, target), proj))
    return out


STRATEGIES = tuple(REGISTRY)
OTHERS = tuple(s for s in STRATEGIES if s != "om_multi")
PER_SIZE = 2                        # strategies beside om_multi (the issue's) at each size, in turn


def strategies_at(k):
    """om_multi and :data:`PER_SIZE` others, in turn: every strategy meets many sizes."""
    return ("om_multi",) + tuple(OTHERS[(PER_SIZE * k + i) % len(OTHERS)] for i in range(PER_SIZE))


@pytest.mark.parametrize("preset_name", tuple(PRESETS))
def test_nothing_seen_at_the_render_size_is_culled(ctx, preset_name):
    """Every size of :data:`SIZES` in turn (a new engine at each, as the add-on builds one
    when the render size changes), the query resolution the add-on picks, om_multi and
    two more strategies at each."""
    rng = np.random.default_rng(30)
    passes, occluded, missed = 0, 0, []
    for k, display in enumerate(SIZES):
        scene = workflow_scene(rng, slit_px=(0.1, 0.5, 1.0, 2.5)[k % 4])
        cams = cameras(rng, *display)
        for m, longest in enumerate(MAX_QUERY):
            res, shown = sizes(display, preset_name, longest)
            with Culler(scene, res, ctx=ctx, display=shown, options=preset(preset_name)) as c:
                truths = [c.renderer.visible_truth(cam, display=shown is not None) for cam in cams]
                for name in strategies_at(2 * k + m):
                    c.set_strategy(name)
                    for j, (cam, truth) in enumerate(zip(cams, truths, strict=True)):
                        r = c.cull(cam, truth=truth, fresh=True)
                        passes += 1
                        occluded += int((r.state == Visibility.OCCLUDED).sum())
                        lost = np.flatnonzero(truth & ~r.visible)
                        if len(lost):
                            missed.append((display, longest, res, shown, name, j, lost.tolist()))
    assert not missed, f"culled what the render shows (display, max query side, query, display, " \
                       f"strategy, camera, objects): {missed[:10]}"
    assert passes == len(SIZES) * len(MAX_QUERY) * (1 + PER_SIZE) * 2
    assert occluded > 0                       # a sweep that culls nothing proves nothing


def test_the_sweep_reaches_the_sizes_it_is_for():
    """Query resolutions below the display's with a different scale per axis (200x60 at a
    largest query side of 16 is 16x5: 12.5 and 12 display pixels a query pixel), one-pixel
    sides, and both presets' display reduction."""
    picked = {(d, p, m): sizes(d, p, m) for d in SIZES for p in PRESETS for m in MAX_QUERY}
    assert picked[((200, 60), "conservative", 16)] == ((16, 5), (200, 60))
    assert picked[((200, 60), "conservative", 1920)] == ((200, 60), None)
    assert picked[((200, 60), "fast", 1920)] == ((100, 30), (200, 60))
    uneven = [k for k, (res, shown) in picked.items()
              if shown is not None and shown[0] * res[1] != shown[1] * res[0]]
    assert len(uneven) > 10
    assert any(min(res) == 1 for res, _ in picked.values())
    met = {}
    for k in range(len(SIZES) * len(MAX_QUERY)):
        for name in strategies_at(k):
            met[name] = met.get(name, 0) + 1
    assert set(met) == set(STRATEGIES) and min(met.values()) >= 8
