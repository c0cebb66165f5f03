"""Invariant checks that several test modules hold the engine's structures to."""

import numpy as np

from core.bounds import MAX, MIN


def check_tree(tree, boxes, max_children):
    """A subdivision tree over ``boxes``: its order a permutation that the node ranges
    partition, no empty leaf, 2..max_children children per inner node, every node's box
    tight around its own items and children."""
    k = len(boxes)
    assert np.array_equal(np.sort(tree.order), np.arange(k))           # a permutation
    # ranges partition the order
    ranges = np.zeros(k, dtype=int)
    for s, c in zip(tree.item_start, tree.item_count, strict=True):
        ranges[s:s + c] += 1
    assert np.all(ranges == 1)
    leaf = tree.child_count == 0
    assert np.all(tree.item_count[leaf] >= 1)                          # no empty leaves
    assert np.all((tree.child_count[~leaf] >= 2) & (tree.child_count[~leaf] <= max_children))
    for node in range(len(tree)):                # tight: own items + children
        own = boxes[tree.order[tree.item_start[node]:tree.item_start[node] + tree.item_count[node]]]
        kids = np.arange(tree.first_child[node], tree.first_child[node] + tree.child_count[node])
        parts = np.concatenate([own, tree.bounds[kids]]) if len(kids) else own
        assert np.array_equal(tree.bounds[node][MIN], parts[:, MIN].min(axis=0))
        assert np.array_equal(tree.bounds[node][MAX], parts[:, MAX].max(axis=0))
        assert np.all(tree.parent[kids] == node) and np.all(tree.depth[kids] == tree.depth[node] + 1)
