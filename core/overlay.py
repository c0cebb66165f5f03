"""Geometry for the debugging overlay, as plain arrays (the add-on hands them to
Blender's ``gpu`` module): box wireframes and the occupancy map as screen quads."""

import numpy as np

from .bounds import BOX_EDGES, corners


def box_lines(boxes):
    """Line-list vertices of box wireframes: ``(k, 2, 3)`` -> ``(k * 24, 3) float32``."""
    return corners(boxes)[:, BOX_EDGES].reshape(-1, 3).astype(np.float32)


def occupancy_quads(grid, x, y, width, height):
    """Triangle-list vertices ``(m * 6, 2) float32`` of the set tiles of an occupancy
    map ``(rows, cols) bool`` (row 0 at the bottom) drawn into the screen rectangle
    at ``(x, y)`` of ``width x height`` pixels."""
    rows, cols = grid.shape
    r, c = np.nonzero(grid)
    tw, th = width / max(cols, 1), height / max(rows, 1)
    x0, y0 = x + c * tw, y + r * th
    x1, y1 = x0 + tw, y0 + th
    quads = np.stack([np.stack([x0, y0], -1), np.stack([x1, y0], -1), np.stack([x1, y1], -1),
                      np.stack([x0, y0], -1), np.stack([x1, y1], -1), np.stack([x0, y1], -1)], axis=1)
    return quads.reshape(-1, 2).astype(np.float32)
