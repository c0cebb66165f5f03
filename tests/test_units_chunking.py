"""Chunking of heavy meshes (core.units) on seeded random meshes: float32 triangle
boxes that contain their float64 triangles, every triangle in exactly one chunk,
chunk boxes around their triangles, chunk trees whose children lie inside their
parents; and the in-place item boxes of the subdivision builders."""

import numpy as np
import pytest

from core import OccError, Scene
from core.bounds import MAX, MIN, contains
from core.engine import make_units
from core.subdivision import BUILDERS, ItemBoxes, build_tree
from core.units import triangle_bounds


def random_mesh(rng, v, f, offset=0.0):
    """Vertices (most not representable in float32) and random triangles."""
    verts = rng.normal(0.0, 10.0, (v, 3)) + offset
    faces = rng.integers(0, v, (f, 3))
    return verts, faces


def chunk_scene(verts, faces, copies=1):
    return Scene.from_arrays([f"o{i}" for i in range(copies)], [(verts, faces)], [0] * copies,
                             np.repeat(np.eye(4)[None], copies, axis=0))


@pytest.mark.parametrize("offset", [0.0, 1e5, -3e7])
def test_triangle_bounds_contain_float64_triangles(offset):
    rng = np.random.default_rng(7)
    verts, faces = random_mesh(rng, 500, 3000, offset)
    verts[:7] = [0.1, 1 / 3, 2 / 3]                      # values float32 rounds up and down
    lo, hi = triangle_bounds(verts, faces)
    assert lo.dtype == hi.dtype == np.float32 and lo.shape == hi.shape == (3, 3000)
    tri = verts[faces]                                   # (f, 3, 3) float64, the reference
    exact_lo, exact_hi = tri.min(axis=1).T, tri.max(axis=1).T
    assert np.all(lo <= exact_lo) and np.all(hi >= exact_hi)           # conservative
    # and tight: at most one float32 step outward
    assert np.all(np.nextafter(lo, np.float32(np.inf)) >= exact_lo.astype(np.float32))
    assert np.all(np.nextafter(hi, np.float32(-np.inf)) <= exact_hi.astype(np.float32))


def test_triangle_bounds_of_float32_data_are_exact():
    rng = np.random.default_rng(8)
    verts, faces = random_mesh(rng, 400, 2000, offset=123.25)
    verts = verts.astype(np.float32).astype(np.float64)     # as read from Blender or glTF
    lo, hi = triangle_bounds(verts, faces)
    tri = verts[faces]
    assert np.array_equal(lo, tri.min(axis=1).T) and np.array_equal(hi, tri.max(axis=1).T)


def test_triangle_bounds_beyond_float32_is_refused():
    verts = np.array([[0, 0, 0], [1e39, 0, 0], [0, 1, 0]], float)
    lo, hi = triangle_bounds(verts, np.array([[0, 1, 2]]))
    with pytest.raises(OccError, match="infinite"):
        build_tree(ItemBoxes(lo, hi))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("builder", ["tree", *BUILDERS])
def test_chunks_partition_the_mesh_and_contain_their_triangles(seed, builder):
    rng = np.random.default_rng(seed)
    f = int(rng.integers(200, 3000))
    verts, faces = random_mesh(rng, int(rng.integers(50, 800)), f, offset=rng.uniform(-1e4, 1e4))
    if seed % 3 == 1:
        faces[: f // 3] = faces[0]                       # many identical triangles
    scene = chunk_scene(verts, faces, copies=2)
    leaf = int(rng.integers(8, 64))
    units = make_units(scene, builder, chunk_triangles=leaf, chunk_min_triangles=1)
    order = units.face_order[0]
    assert np.array_equal(np.sort(order), np.arange(f))              # every triangle once
    mine = units.object == 0
    first, count = units.first[mine], units.count[mine]
    cover = np.zeros(f, dtype=int)
    for s, c in zip(first, count, strict=True):
        cover[s:s + c] += 1
    assert np.all(cover == 1) and np.all(count >= 1)                 # chunks tile the face order
    tri = verts[faces[order]]                                        # triangles in chunk order
    for s, c, box in zip(first, count, units.local_bounds[mine], strict=True):
        t = tri[s:s + c].reshape(-1, 3)
        assert np.all(box[MIN] <= t.min(axis=0)) and np.all(t.max(axis=0) <= box[MAX])
    # the chunk tree: chunk i owned by one node; children inside parents; every box
    # inside its node's
    tree = units.trees[0]
    assert units.trees[1] is tree                                    # the shared mesh's chunks are shared
    assert np.array_equal(np.sort(tree.order), np.arange(len(first)))
    kids = np.flatnonzero(tree.parent >= 0)
    assert np.all(contains(tree.bounds[tree.parent[kids]], tree.bounds[kids]))
    node_of = np.repeat(np.arange(len(tree)), tree.item_count)
    chunk_of = tree.order[np.concatenate([np.arange(s, s + c) for s, c in
                                          zip(tree.item_start, tree.item_count, strict=True)])]
    assert np.all(contains(tree.bounds[node_of], units.local_bounds[mine][chunk_of]))


@pytest.mark.parametrize("builder", BUILDERS)
def test_item_boxes_build_matches_array_build(builder):
    """The in-place path builds the same tree as the (k, 2, 3) path and leaves the
    corner arrays in the tree's item order."""
    rng = np.random.default_rng(11)
    lo = rng.uniform(-50, 50, (3000, 3))
    boxes = np.stack([lo, lo + rng.exponential(1.0, (3000, 3))], axis=1)
    a = build_tree(boxes, builder, leaf_size=16, max_children=4)
    items = ItemBoxes(np.ascontiguousarray(boxes[:, MIN].T), np.ascontiguousarray(boxes[:, MAX].T))
    b = build_tree(items, builder, leaf_size=16, max_children=4)
    assert np.array_equal(a.order, b.order) and np.array_equal(a.bounds, b.bounds)
    assert np.array_equal(items.lo, boxes[a.order, MIN].T) and np.array_equal(items.hi, boxes[a.order, MAX].T)


def test_item_boxes_shape_is_checked():
    with pytest.raises(OccError, match=r"\(3, k\)"):
        ItemBoxes(np.zeros((2, 5)), np.zeros((2, 5)))


@pytest.mark.parametrize("seed", range(8))
def test_planned_levels_keep_the_invariants(seed, monkeypatch):
    """pHBVO decides several levels from one sample above PLAN_ITEMS items (a 20 M
    triangle mesh moves its items once per PLAN_DEPTH levels): lowered here so that
    seeded random boxes take that path, the tree is still a tight partition."""
    import core.subdivision as sd
    from tests.checks import check_tree
    from tests.scenes import random_boxes

    monkeypatch.setattr(sd, "PLAN_ITEMS", 150)
    plans = []
    classify = sd._classify
    monkeypatch.setattr(sd, "_classify", lambda *a: plans.append(a[2]) or classify(*a))
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, int(rng.integers(400, 4000)))
    max_children = [2, 4, 8][seed % 3]
    tree = build_tree(boxes, "pHBVO", leaf_size=int(rng.integers(4, 40)), max_children=max_children,
                      pull_up=bool(seed % 2))
    check_tree(tree, boxes, max_children)
    assert plans                                                        # the planned path ran
    verts, faces = random_mesh(rng, 3000, 6000)
    units = make_units(chunk_scene(verts, faces), "tree", chunk_triangles=16, chunk_min_triangles=1)
    order = units.face_order[0]
    assert np.array_equal(np.sort(order), np.arange(len(faces)))
    tri = verts[faces[order]]
    for s, c, box in zip(units.first, units.count, units.local_bounds, strict=True):
        t = tri[s:s + c].reshape(-1, 3)
        assert np.all(box[MIN] <= t.min(axis=0)) and np.all(t.max(axis=0) <= box[MAX])
    tree = units.trees[0]
    kids = np.flatnonzero(tree.parent >= 0)
    assert np.all(contains(tree.bounds[tree.parent[kids]], tree.bounds[kids]))


@pytest.mark.parametrize("pull_up", [False, True])
def test_plan_parts_follow_their_planes(pull_up):
    """Each item's part in a plan is the one its centre's side of every plane on its
    path names (an item longer than a node's limit stays at that node, in its own
    part), and every plan node's parts are one run of labels: partitioned by label,
    each node's items are one range."""
    import core.subdivision as sd

    rng = np.random.default_rng(5)
    lo = rng.uniform(-50, 50, (3, 20000)).astype(np.float32)
    hi = lo + rng.exponential(1.0, (3, 20000)).astype(np.float32)
    hi[:, :40] += 60.0                                                 # a few long items to pull up
    plan = sd._plans([(lo, hi)], 256, pull_up)
    assert plan.depth == 7 and plan.parts[0] > 100                     # seven levels at once here
    assert np.isfinite(plan.limit).any() == pull_up
    labels = sd._classify(lo, hi, plan)
    twice = lo.astype(np.float64) + hi
    size = (hi - lo).max(axis=0)
    for i in range(0, 20000, 7):                                       # the plan walked item by item
        p = 0
        while plan.child[p, 0] != p and not size[i] > plan.limit[p]:
            p = plan.child[p, int(twice[plan.axis[p], i] >= plan.twice[p])]
        assert labels[i] == plan.label[p], i
    if pull_up:
        inner = plan.child[:, 0] != np.arange(len(plan.axis))
        assert np.isin(labels[:40], plan.label[inner]).any()           # pulled up at some inner node
    for p in range(len(plan.axis)):                                    # depth first: a node's parts are a run
        kids = plan.child[p]
        if kids[0] != p:
            assert plan.first[kids[0]] == plan.first[p] + 1
            assert plan.first[kids[1]] == plan.first[kids[0]] + plan.parts[kids[0]]
            assert plan.parts[p] == 1 + plan.parts[kids[0]] + plan.parts[kids[1]]
