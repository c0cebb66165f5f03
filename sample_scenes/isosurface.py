"""``isosurface``: a marching-cubes surface from a uniform grid -- a ventricle-like
cave (a winding tunnel with side chambers), cut into objects along a regular
grid of blocks, like the ORSD case of the subdivision paper.  The walk stays
on the tunnel's centre line, inside the cavity."""

import numpy as np

GRID = 112            # samples per axis (full size)
BLOCK = 8             # grid cells per object block per axis
RADIUS = 0.11         # tunnel radius in the unit cube


def _centre_line(t):
    """Points of the tunnel's centre line for parameters ``t`` in [0, 1], ``(k, 3)``."""
    t = np.asarray(t, dtype=np.float64)
    return np.stack([0.15 + 0.7 * t, 0.5 + 0.25 * np.sin(2 * np.pi * t), 0.5 + 0.2 * np.sin(3 * np.pi * t)],
                    axis=-1)


def field(points, rng_seed=5):
    """Scalar field at ``(k, 3)`` points in the unit cube: negative inside the cave."""
    rng = np.random.default_rng(rng_seed)
    line = _centre_line(np.linspace(0, 1, 200))
    d = np.full(len(points), np.inf)
    for chunk in range(0, len(points), 200_000):          # bounded memory
        p = points[chunk:chunk + 200_000]
        d[chunk:chunk + 200_000] = np.sqrt(((p[:, None] - line[None]) ** 2).sum(-1)).min(axis=1)
    blobs = _centre_line(rng.uniform(0.1, 0.9, 6)) + rng.normal(scale=0.08, size=(6, 3))
    chambers = np.sqrt(((points[:, None] - blobs[None]) ** 2).sum(-1)).min(axis=1)
    wobble = 0.015 * np.sin(23 * points[:, 0]) * np.cos(17 * points[:, 1]) * np.sin(19 * points[:, 2])
    return np.minimum(d - RADIUS, chambers - 0.08) + wobble


def build(rng, small=False):
    import trimesh
    try:
        from skimage.measure import marching_cubes
    except ImportError:
        raise ImportError("the isosurface sample needs scikit-image: pip install scikit-image") from None
    n = 48 if small else GRID
    axis = np.linspace(0.0, 1.0, n)
    pts = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    vol = field(pts).reshape(n, n, n)
    vol[[0, -1]] = vol[:, [0, -1]] = 1.0                 # closed at the borders
    vol[:, :, [0, -1]] = 1.0
    verts, faces, _, _ = marching_cubes(vol, level=0.0, spacing=(1 / (n - 1),) * 3)
    verts = verts * 40.0                                  # a 40 m cave
    block = (verts[faces].mean(axis=1) / 40.0 * (n - 1) // BLOCK).astype(np.int64)
    key = (block[:, 0] * 1000 + block[:, 1]) * 1000 + block[:, 2]
    scene = trimesh.Scene()
    order = np.argsort(key, kind="stable")
    keys, starts = np.unique(key[order], return_index=True)
    ends = np.append(starts[1:], len(order))
    for k, s, e in zip(keys, starts, ends, strict=True):     # one object per occupied block
        f = faces[order[s:e]]
        used, inv = np.unique(f, return_inverse=True)
        mesh = trimesh.Trimesh(verts[used], inv.reshape(-1, 3), process=False)
        name = f"cave/block_{k // 1_000_000:02d}_{k // 1000 % 1000:02d}_{k % 1000:02d}"
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene


def paths(small=False):
    n = 90
    t = np.linspace(0.03, 0.97, n)
    eye = _centre_line(t) * 40.0
    ahead = _centre_line(np.minimum(t + 0.05, 1.0)) * 40.0
    ahead[-1] = eye[-1] + (eye[-1] - eye[-2])
    frames = [{"eye": e.tolist(), "target": g.tolist(), "up": [0, 0, 1], "fov_y_deg": 75.0,
               "aspect": 16 / 9, "near": 0.05, "far": 80.0, "ortho_height": None}
              for e, g in zip(eye, ahead, strict=True)]
    return {"walk": {"frames": frames}}
