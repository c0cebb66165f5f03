"""Seeded property tests: frustum, boxes, hierarchy and occupancy map invariants."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from core import Camera
from core.bounds import MAX, MIN, contains, corners, transform_boxes
from core.frustum import classify, planes_from_matrix
from core.hierarchy import build_from_tree
from core.occupancy import OccupancyMap, free_tile_first, project_rects
from tests.reference import classify_gathered, corners_outside_brute, non_overlapping_first

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)
seeds = st.integers(0, 2**31 - 1)


def random_boxes(rng, n, spread=50.0):
    lo = rng.uniform(-spread, spread, (n, 3))
    size = rng.exponential(3.0, (n, 3)) * (rng.random((n, 3)) > 0.1)   # some zero extents
    return np.stack([lo, lo + size], axis=1)


def random_camera(rng):
    eye = rng.uniform(-40, 40, 3)
    target = eye + rng.normal(size=3)
    ortho = float(rng.uniform(1, 30)) if rng.random() < 0.3 else None
    return Camera.look_at(eye, target, up=rng.normal(size=3), fov_y_deg=rng.uniform(5, 170),
                          aspect=rng.uniform(0.2, 5), near=rng.uniform(0.01, 2),
                          far=rng.uniform(50, 500), ortho_height=ortho)


@SETTINGS
@given(seeds)
def test_frustum_never_rejects_what_corner_test_keeps(seed):
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    boxes = random_boxes(rng, 200) - cam.eye
    planes = planes_from_matrix(cam.relative_view_projection())
    outside, _ = classify(planes, boxes)
    # The brute-force corner test is itself conservative: a box it keeps may be
    # outside, but a box it rejects is outside one plane entirely.
    kept_by_brute = ~corners_outside_brute(planes, boxes)
    assert not np.any(outside & kept_by_brute)


@SETTINGS
@given(seeds)
def test_plane_masking_is_exact_for_children(seed):
    """A child tested only against its parent's remaining planes gets the same
    outside answer as with all planes."""
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    planes = planes_from_matrix(cam.relative_view_projection())
    parents = random_boxes(rng, 50, 30) - cam.eye
    t = rng.random((50, 2, 3))
    lo = parents[:, MIN] + (parents[:, MAX] - parents[:, MIN]) * np.minimum(t[:, 0], t[:, 1])
    hi = parents[:, MIN] + (parents[:, MAX] - parents[:, MIN]) * np.maximum(t[:, 0], t[:, 1])
    children = np.stack([lo, hi], axis=1)
    p_out, p_mask = classify(planes, parents)
    c_out_masked, _ = classify(planes, children, p_mask)
    c_out_full, _ = classify(planes, children)
    keep = ~p_out
    assert np.array_equal(c_out_masked[keep], c_out_full[keep])


@SETTINGS
@given(seeds)
def test_transformed_boxes_hold_transformed_corners(seed):
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, 30)
    m = np.repeat(np.eye(4)[None], 30, axis=0)
    m[:, :3, :3] = rng.normal(size=(30, 3, 3))
    m[:, :3, 3] = rng.normal(scale=1e3, size=(30, 3))
    world = transform_boxes(boxes, m)
    c = corners(boxes)
    moved = np.einsum("nij,nkj->nki", m[:, :3, :3], c) + m[:, None, :3, 3]
    slack = 1e-9 * (1 + np.abs(moved).max())
    assert np.all(moved >= world[:, None, MIN] - slack) and np.all(moved <= world[:, None, MAX] + slack)


def random_tree(rng, n):
    """A random forest of tree nodes: some groups, each object at most once."""
    groups = rng.integers(0, max(1, n // 3) + 1)
    t = groups + n
    parent = np.full(t, -1)
    for i in range(1, t):
        if rng.random() < 0.8:
            parent[i] = rng.integers(0, i)
    perm = rng.permutation(t)                 # shuffle so parents are not always earlier
    inv = np.argsort(perm)
    parent = np.where(parent[perm] >= 0, inv[np.maximum(parent[perm], 0)], -1)
    obj = np.full(t, -1)
    carriers = rng.choice(t, size=min(t, n - rng.integers(0, 3) if n > 2 else n), replace=False)
    obj[carriers] = np.arange(len(carriers))
    return parent, obj


@SETTINGS
@given(seeds, st.integers(1, 300), st.integers(2, 12))
def test_hierarchy_invariants(seed, n, max_children):
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, n)
    parent, obj = random_tree(rng, n)
    h = build_from_tree(boxes, parent, obj, max_children)
    leaves = np.flatnonzero(h.is_leaf)
    # every object in exactly one leaf
    assert np.array_equal(np.sort(h.leaf_unit[leaves]), np.arange(n))
    assert np.all(h.bounds[leaves] == boxes[h.leaf_unit[leaves]])
    inner = np.flatnonzero(~h.is_leaf)
    assert np.all(h.child_count[inner] >= 2) and np.all(h.child_count[inner] <= max_children)
    for i in inner:     # test code: children inside parents, parent box = union (tight)
        kids = np.arange(h.first_child[i], h.first_child[i] + h.child_count[i])
        assert np.all(h.parent[kids] == i)
        assert np.all(contains(np.repeat(h.bounds[i][None], len(kids), 0), h.bounds[kids]))
        assert np.array_equal(h.bounds[i][MIN], h.bounds[kids][:, MIN].min(axis=0))
        assert np.array_equal(h.bounds[i][MAX], h.bounds[kids][:, MAX].max(axis=0))
    # refit after moving every box keeps the union property
    moved = boxes + rng.normal(size=(n, 1, 3))
    h.refit(moved)
    assert np.array_equal(h.bounds[0][MIN], moved[:, MIN].min(axis=0))
    assert np.array_equal(h.bounds[0][MAX], moved[:, MAX].max(axis=0))


def test_hierarchy_follows_the_scene_tree():
    """Objects of one tree group stay together under one node."""
    rng = np.random.default_rng(1)
    boxes = random_boxes(rng, 6)
    parent = np.array([-1, -1, 0, 0, 0, 1, 1, 1])
    obj = np.array([-1, -1, 0, 1, 2, 3, 4, 5])
    h = build_from_tree(boxes, parent, obj, 8)
    assert h.child_count[0] == 2
    groups = [set(h.leaf_unit[h.leaves_below([c])]) for c in (1, 2)]
    assert sorted(map(sorted, groups)) == [[0, 1, 2], [3, 4, 5]]


@SETTINGS
@given(seeds, st.integers(1, 400), st.integers(1, 300))
def test_occupancy_set_and_tests_match_brute_force(seed, w, h):
    rng = np.random.default_rng(seed)
    om = OccupancyMap(w, h, tiles=int(rng.integers(1, 5000)))
    assert om.rows * om.cols <= max(1, 5000) and om.cols <= w and om.rows <= h
    def rects(k):
        x = np.sort(rng.integers(0, w, (k, 2)), axis=1)
        y = np.sort(rng.integers(0, h, (k, 2)), axis=1)
        return np.column_stack([x[:, 0], y[:, 0], x[:, 1], y[:, 1]])
    drawn = rects(int(rng.integers(0, 6)))
    om.set(drawn)
    ref = np.zeros((om.rows, om.cols), bool)
    for t in om.tile_rects(drawn):          # reference, per rectangle
        ref[t[1]:t[3] + 1, t[0]:t[2] + 1] = True
    assert np.array_equal(om.grid, ref)
    probe = rects(50)
    tiles = om.tile_rects(probe)
    sub = [ref[t[1]:t[3] + 1, t[0]:t[2] + 1] for t in tiles]
    assert np.array_equal(om.any_empty(probe), [not s.all() for s in sub])
    assert np.array_equal(om.all_covered(probe), [s.all() for s in sub])
    assert np.array_equal(om.any_set(probe), [s.any() for s in sub])
    bits = np.unpackbits(om.words().view(np.uint8), bitorder="little")[: om.rows * om.cols]
    assert np.array_equal(bits.reshape(om.rows, om.cols).astype(bool), om.grid)
    om.clear()
    assert not om.grid.any() and om.any_empty(probe).all()


def test_default_occupancy_map_is_the_papers_bitfield():
    om = OccupancyMap(1024, 1024)
    assert om.rows * om.cols == 512 * 32 and len(om.words()) == 512
    wide = OccupancyMap(1920, 1080)
    assert wide.rows * wide.cols <= 512 * 32 and abs(wide.cols / wide.rows - 16 / 9) < 0.1


@SETTINGS
@given(seeds)
def test_rects_contain_every_covered_pixel_centre(seed):
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    w, h = int(rng.integers(1, 200)), int(rng.integers(1, 200))
    boxes = random_boxes(rng, 40, 20) + cam.eye + cam.direction * 25 - cam.eye
    clip = cam.relative_view_projection()
    rects, crosses = project_rects(boxes, clip, w, h)
    c = corners(boxes)
    hom = np.concatenate([c, np.ones(c.shape[:2] + (1,))], axis=2) @ clip.T
    ok = ~crosses
    ndc = hom[ok, :, :2] / hom[ok, :, 3:4]
    px = (ndc[..., 0] + 1) * 0.5 * w
    py = (ndc[..., 1] + 1) * 0.5 * h
    # every on-screen pixel centre inside the corners' hull range lies in the rect
    i0 = np.clip(np.ceil(px.min(1) - 0.5), 0, w - 1)
    i1 = np.clip(np.floor(px.max(1) - 0.5), 0, w - 1)
    j0 = np.clip(np.ceil(py.min(1) - 0.5), 0, h - 1)
    j1 = np.clip(np.floor(py.max(1) - 0.5), 0, h - 1)
    r = rects[ok]
    assert np.all(r[:, 0] <= i0) and np.all(i1 <= r[:, 2])
    assert np.all(r[:, 1] <= j0) and np.all(j1 <= r[:, 3])
    # boxes crossing the near plane: every point of the box in front of the plane
    # (sampled on a grid through the box) projects inside the clipped rectangle
    near = planes_from_matrix(clip)[4]
    g = np.linspace(0.0, 1.0, 9)
    t = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    for b, r in zip(boxes[crosses], rects[crosses], strict=True):
        p = b[0] + t * (b[1] - b[0])
        p = p[p @ near[:3] + near[3] > 1e-9 * np.abs(p).max()]
        if not len(p):
            continue
        hp = np.concatenate([p, np.ones((len(p), 1))], axis=1) @ clip.T
        qx = (hp[:, 0] / hp[:, 3] + 1) * 0.5 * w
        qy = (hp[:, 1] / hp[:, 3] + 1) * 0.5 * h
        assert np.all(r[0] <= np.clip(np.floor(qx - 0.5), 0, w - 1))
        assert np.all(np.clip(np.ceil(qx - 0.5), 0, w - 1) <= r[2])
        assert np.all(r[1] <= np.clip(np.floor(qy - 0.5), 0, h - 1))
        assert np.all(np.clip(np.ceil(qy - 0.5), 0, h - 1) <= r[3])


def test_floor_crossing_the_near_plane_is_clipped_not_the_whole_screen():
    """A floor that passes under the eye (it crosses the near plane)
    gets the rectangle of its part in front of the near plane -- the lower half of
    a level view -- not the whole screen, so it does not fill the occupancy map."""
    cam = Camera.look_at((0, 0, 1.7), (10, 0, 1.7), up=(0, 0, 1), fov_y_deg=60, aspect=1.5,
                         near=0.1, far=100)
    floor = np.array([[[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]]]) - cam.eye
    w, h = 96, 64
    rects, crosses = project_rects(floor, cam.relative_view_projection(), w, h)
    assert crosses[0]
    x0, y0, x1, y1 = rects[0]
    assert (x0, x1, y0) == (0, w - 1, 0)
    assert y1 < h // 2                     # nothing of a floor below the eye is above the horizon


@SETTINGS
@given(seeds)
def test_non_overlapping_first_is_the_sequential_greedy(seed):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(0, 60))
    x = np.sort(rng.integers(0, 40, (k, 2)), axis=1)
    y = np.sort(rng.integers(0, 40, (k, 2)), axis=1)
    t = np.column_stack([x[:, 0], y[:, 0], x[:, 1], y[:, 1]]).reshape(-1, 4)
    grid = np.zeros((41, 41), bool)
    expect = []
    for r in t:                              # reference: one cleared map, filled in order
        free = not grid[r[1]:r[3] + 1, r[0]:r[2] + 1].any()
        expect.append(free)
        if free:
            grid[r[1]:r[3] + 1, r[0]:r[2] + 1] = True
    assert np.array_equal(non_overlapping_first(t), np.array(expect, dtype=bool))


@SETTINGS
@given(seeds)
def test_free_tile_first_is_the_papers_sequential_rule(seed):
    """A rectangle joins the test list while one of its tiles is still free in the
    list's own map (Staneker et al. 2004), not only when it overlaps nothing taken."""
    rng = np.random.default_rng(seed)
    k = int(rng.integers(0, 60))
    x = np.sort(rng.integers(0, 40, (k, 2)), axis=1)
    y = np.sort(rng.integers(0, 40, (k, 2)), axis=1)
    t = np.column_stack([x[:, 0], y[:, 0], x[:, 1], y[:, 1]]).reshape(-1, 4)
    grid = np.zeros((41, 41), bool)
    expect = []
    for r in t:                              # reference: one cleared map, filled in order
        free = not grid[r[1]:r[3] + 1, r[0]:r[2] + 1].all()
        expect.append(free)
        if free:
            grid[r[1]:r[3] + 1, r[0]:r[2] + 1] = True
    assert np.array_equal(free_tile_first(t, 41, 41), np.array(expect, dtype=bool))


def test_test_list_takes_a_box_that_still_has_a_free_tile():
    """Two boxes overlapping by one tile column: the old rule sent the second to a
    later list, the papers' rule takes both in one multiple query."""
    t = np.array([[0, 0, 4, 4], [4, 0, 8, 4], [1, 1, 3, 3]])
    assert free_tile_first(t, 10, 10).tolist() == [True, True, False]
    assert non_overlapping_first(t).tolist() == [True, False, False]


@SETTINGS
@given(seeds)
def test_fast_classification_equals_the_reference(seed):
    """The engine's per-pass plane test (two matrix products) answers exactly as
    core.frustum.classify (gathered p- and n-vertices), masks included."""
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    boxes = random_boxes(rng, 200) - cam.eye
    planes = planes_from_matrix(cam.relative_view_projection())
    masks = rng.integers(0, 64, len(boxes)).astype(np.uint8)
    for m in (None, masks):
        a, b = classify_gathered(planes, boxes, m), classify(planes, boxes, m)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
