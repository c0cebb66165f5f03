"""Subdivision builders: partition, tightness, branching, SAH quality, pull-up,
degenerate inputs -- on seeded random boxes."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core import OccError
from core.bounds import MAX, MIN
from core.subdivision import BUILDERS, build_tree, choose_leaf_size, sah_cost, worth_chunking
from tests.checks import check_tree
from tests.scenes import random_boxes

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True)


@SETTINGS
@given(st.integers(0, 2**31 - 1), st.integers(1, 600), st.sampled_from(BUILDERS),
       st.sampled_from([2, 4, 8]), st.integers(1, 40), st.booleans())
def test_builder_invariants(seed, k, builder, max_children, leaf_size, pull_up):
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, k)
    tree = build_tree(boxes, builder, leaf_size, max_children, pull_up)
    check_tree(tree, boxes, max_children)


@SETTINGS
@given(st.integers(0, 2**31 - 1), st.integers(50, 2000), st.integers(1, 16))
def test_sah_never_worse_than_median(seed, k, leaf_size):
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, k)
    sah = build_tree(boxes, "pHBVO", leaf_size, 2, pull_up=False)
    median = build_tree(boxes, "balanced", leaf_size, 2, pull_up=False)
    assert sah_cost(sah) <= sah_cost(median) * (1 + 1e-9)


def test_huge_triangles_are_pulled_up():
    rng = np.random.default_rng(3)
    lo = rng.uniform(0, 100, (5000, 3))
    small = np.stack([lo, lo + 0.1], axis=1)
    huge = np.array([[[0, 0, 0], [100, 100, 1]], [[0, 0, 50], [100, 1, 100]], [[0, 0, 0], [1, 100, 100]]])
    boxes = np.concatenate([small, huge])
    tree = build_tree(boxes, "pHBVO", leaf_size=64, max_children=4, pull_up=True)
    where = {int(tree.order[i]): n for n in range(len(tree))
             for i in range(tree.item_start[n], tree.item_start[n] + tree.item_count[n])}
    assert all(tree.depth[where[5000 + j]] <= 2 for j in range(3))
    leaf = tree.child_count == 0
    assert (tree.bounds[leaf, MAX] - tree.bounds[leaf, MIN]).max() < 60
    no_pull = build_tree(boxes, "pHBVO", leaf_size=64, max_children=4, pull_up=False)
    nleaf = no_pull.child_count == 0
    assert (no_pull.bounds[nleaf, MAX] - no_pull.bounds[nleaf, MIN]).max() >= 99


@pytest.mark.parametrize("builder", BUILDERS)
@pytest.mark.parametrize("case", ["one", "identical", "flat", "fewer_than_leaf"])
def test_degenerate_inputs(builder, case):
    rng = np.random.default_rng(1)
    if case == "one":
        boxes = np.array([[[0, 0, 0], [1, 1, 1]]], float)
    elif case == "identical":
        boxes = np.repeat([[[1, 2, 3], [1, 2, 3]]], 500, axis=0).astype(float)
    elif case == "flat":
        lo = rng.uniform(0, 10, (300, 3))
        lo[:, 1] = 5.0
        boxes = np.stack([lo, lo + [1, 0, 1]], axis=1)
    else:
        boxes = random_boxes(rng, 10)
    tree = build_tree(boxes, builder, leaf_size=64, max_children=4)
    check_tree(tree, boxes, 4)


def test_bad_input_is_a_clear_error():
    with pytest.raises(OccError, match="NaN"):
        build_tree(np.full((3, 2, 3), np.nan))
    with pytest.raises(OccError, match="unknown builder"):
        build_tree(np.zeros((3, 2, 3)), "kdtree")
    with pytest.raises(OccError, match=r"\(n, 2, 3\)"):
        build_tree(np.zeros((3, 3)))


def test_cost_model():
    # more expensive queries -> bigger chunks; more expensive triangles -> smaller
    a = choose_leaf_size(1_000_000, 30.0, 1.0, 20.0)
    assert choose_leaf_size(1_000_000, 60.0, 1.0, 20.0) > a > choose_leaf_size(1_000_000, 30.0, 1.0, 80.0)
    assert choose_leaf_size(100, 30.0, 1.0, 20.0) == 100
    assert choose_leaf_size(10**7, 30.0, 1.0, 20.0) == 1550
    assert not worth_chunking(5000, 30.0, 20.0)
    assert worth_chunking(1_000_000, 30.0, 20.0)
