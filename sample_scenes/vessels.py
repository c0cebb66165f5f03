"""``vessels``: the low-occlusion case -- a branching tube tree in open space.

Each segment is its own object (a shared unit tube, moved and scaled), so an
orbit sees nearly everything: culling must not cost here.
"""

import numpy as np

from ._shapes import SceneBuilder, align_z, tube


def _branches(rng, max_leaves):
    """Segments (start, end, radius, depth) of a random bifurcating tree, breadth first."""
    segs = [(np.zeros(3), np.array([0.0, 0.0, 4.0]), 0.5, 0)]
    front = [0]
    leaves = []
    while front:
        i = front.pop(0)
        start, end, radius, depth = segs[i]
        if depth >= 9 or (len(leaves) + len(front) >= max_leaves):
            leaves.append(i)
            continue
        d = (end - start) / np.linalg.norm(end - start)
        for side in (-1, 1):
            axis = np.cross(d, rng.normal(size=3))
            axis /= np.linalg.norm(axis)
            ang = side * rng.uniform(0.3, 0.7)
            nd = d * np.cos(ang) + np.cross(axis, d) * np.sin(ang)
            length = np.linalg.norm(end - start) * rng.uniform(0.7, 0.9)
            segs.append((end, end + nd * length, radius * 0.75, depth + 1))
            front.append(len(segs) - 1)
    return segs, leaves


def build(rng, small=False):
    segs, _ = _branches(rng, 40 if small else 180)
    sb = SceneBuilder()
    sections, rings = (16, 6) if small else (32, 18)
    for k, (start, end, radius, depth) in enumerate(segs):
        sb.add(f"vessel/seg_{k:03d}_d{depth}", "unit_tube",
               lambda: tube(1.0, 1.0, sections, rings), align_z(start, end, radius))
    return sb.scene


def paths(small=False):
    n = 90
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    centre = np.array([0.0, 0.0, 9.0])
    eye = centre + np.stack([24 * np.cos(t), 24 * np.sin(t), 4 * np.sin(2 * t)], axis=1)
    frames = [{"eye": e.tolist(), "target": centre.tolist(), "up": [0, 0, 1], "fov_y_deg": 55.0,
               "aspect": 16 / 9, "near": 0.1, "far": 200.0, "ortho_height": None} for e in eye]
    return {"orbit": {"frames": frames}}
