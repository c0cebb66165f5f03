"""The stages the occupancy-map strategies share (Staneker et al. 2003, 2004): the
occupancy-driven descent (stage 1), test lists arranged by occupancy maps (stage 2), and
acting on query answers.  Each takes the :class:`~core.cull.view_pass.CullPass` ``cp``."""

import numpy as np

from ..occupancy import X0, X1, Y0, Y1, free_tile_first

MAX_TEST_CANDIDATES = 512      # bounds the pairwise work of one test list


def stage1(cp, front, chunk):
    """Occupancy-driven descent: front to back in chunks of ``chunk`` nodes; a node
    whose rectangle still has an empty tile (or that crosses the near plane) is
    drawn (leaf) or opened (inner) without a query, the others are returned
    (pending), nearest first."""
    pending = []
    while len(front):
        # The map only ever fills, so a node with no empty tile now never gets one:
        # defer all such nodes at once, chunk only those still in doubt.
        hopeless = (~cp.crosses[front] & ~cp.free[front]
                    & ~cp.om.any_empty_tiles(cp.tiles[front]))
        pending.append(front[hopeless])
        front = cp.sort_near(front[~hopeless])
        head, front = front[:chunk], front[chunk:]
        crosses, free = cp.crosses[head], cp.free[head]
        empty = cp.om.any_empty_tiles(cp.tiles[head])
        leaf = cp.tree.is_leaf[head]
        tiles = cp.tiles[head]
        # Within a chunk, a node whose tiles all lie under one nearer leaf that is
        # drawn in this chunk would find them occupied: defer it too.
        proven = crosses | free | (empty & ~nearer(tiles, empty & leaf, inside=True))
        # A node over (on screen) and behind a nearer inner node opened in this chunk
        # was judged on a map that lacks that node's contents: it goes back to the
        # front, judged again beside that node's children.  (Deferred to a query
        # instead, it left the map without its own contents, and every farther node
        # it covers was then drawn unqueried: a collection holding one object in front
        # of a wall and others behind it culled none of them.)
        again = proven & ~crosses & ~free & nearer(tiles, proven & ~leaf, inside=False)
        proven &= ~again
        cp.stats.near_visible += int(crosses.sum())
        cp.stats.queries_skipped += int((proven & ~crosses & ~free).sum())
        cp.draw_leaves(head[proven & leaf & ~cp.predrawn[head]])
        front = np.concatenate([front, head[again], cp.children_in_frustum(head[proven & ~leaf])])
        pending.append(head[~proven & ~again])
    return np.concatenate(pending) if pending else np.zeros(0, dtype=np.int64)


def nearer(tiles, marked, inside):
    """``(k,) bool``: rectangle i lies inside (``inside``) or overlaps rectangle j for
    some earlier j with ``marked[j]``."""
    t = tiles
    if inside:
        rel = ((t[None, :, X0] <= t[:, None, X0]) & (t[:, None, X1] <= t[None, :, X1])
               & (t[None, :, Y0] <= t[:, None, Y0]) & (t[:, None, Y1] <= t[None, :, Y1]))
    else:
        rel = ((t[None, :, X0] <= t[:, None, X1]) & (t[:, None, X0] <= t[None, :, X1])
               & (t[None, :, Y0] <= t[:, None, Y1]) & (t[:, None, Y0] <= t[None, :, Y1]))
    rel &= np.tri(len(t), len(t), -1, dtype=bool) & marked[None, :]
    return rel.any(axis=1)


def test_list(cp, pending):
    """Split sorted ``pending`` into (test list, rest) by the papers' rule: a box
    joins while one of its tiles is free in the list's own (cleared) map."""
    cand = pending[:MAX_TEST_CANDIDATES]
    taken = free_tile_first(cp.tiles[cand], cp.om.rows, cp.om.cols)
    return cand[taken], np.concatenate([cand[~taken], pending[MAX_TEST_CANDIDATES:]])


def frustum_leaves_below(cp, nodes):
    """Leaves inside the frustum in the subtrees of reached ``nodes``, with their
    rectangles (the nodes between are reached without: only the leaves are tested,
    drawn and marked in the map)."""
    out, front = [], nodes
    while len(front):
        leaf = cp.tree.is_leaf[front]
        out.append(front[leaf])
        front = cp.children_in_frustum(front[~leaf], geometry=False)
    leaves = np.concatenate(out) if out else np.zeros(0, dtype=np.int64)
    bare = leaves[~cp.has_geometry[leaves]]
    if len(bare):
        cp.ensure_geometry(bare)
    return leaves


def resolve(cp, nodes, visible):
    """Act on query answers: occlude the hidden, draw visible leaves, open visible
    inner nodes; returns the opened children."""
    cp.occlude(nodes[~visible])
    vis = nodes[visible]
    leaf = cp.tree.is_leaf[vis]
    cp.draw_leaves(vis[leaf])
    return cp.children_in_frustum(vis[~leaf])
