import numpy as np

from core.overlay import box_lines, occupancy_quads


def test_box_lines_are_the_twelve_edges():
    lines = box_lines(np.array([[[0, 0, 0], [1, 2, 3]]], float)).reshape(12, 2, 3)
    length = np.linalg.norm(lines[:, 1] - lines[:, 0], axis=1)
    assert sorted(length.tolist()) == [1.0] * 4 + [2.0] * 4 + [3.0] * 4
    assert len({tuple(p) for p in lines.reshape(-1, 3).tolist()}) == 8


def test_occupancy_quads_cover_set_tiles():
    grid = np.zeros((4, 8), bool)
    grid[0, 0] = grid[3, 7] = True
    q = occupancy_quads(grid, 10, 20, 80, 40).reshape(-1, 6, 2)
    assert len(q) == 2
    assert q[0].min(axis=0).tolist() == [10, 20] and q[0].max(axis=0).tolist() == [20, 30]
    assert q[1].min(axis=0).tolist() == [80, 50] and q[1].max(axis=0).tolist() == [90, 60]
    assert occupancy_quads(np.zeros((3, 3), bool), 0, 0, 9, 9).shape == (0, 2)
