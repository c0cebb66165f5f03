"""``city``: the high-depth-complexity case.

A grid of blocks; every block holds buildings with closed shells (four walls and
a roof) whose rooms carry high-polygon furniture -- most triangles are inside,
hidden from the street.  Cars stand in the streets.  Full size: 2,700+ objects
and 4.4 million triangles, from a handful of shared meshes.
"""

import numpy as np

from ._shapes import SceneBuilder, box, cylinder, place, sphere

BLOCK = 40.0          # block pitch (m); streets are 10 m wide
STREET = 10.0


def _car():
    import trimesh
    body = box((4.2, 1.8, 1.0))
    body.apply_translation((0, 0, 0.8))
    cabin = sphere(2, 1.0)
    cabin.apply_scale((1.3, 0.8, 0.55))
    cabin.apply_translation((-0.2, 0, 1.3))
    wheels = []
    for x in (-1.4, 1.4):
        for y in (-0.95, 0.95):
            w = cylinder(0.35, 0.25, 48)
            w.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
            w.apply_translation((x, y, 0.35))
            wheels.append(w)
    return trimesh.util.concatenate([body, cabin, *wheels])


def build(rng, small=False):
    blocks = 2 if small else 6
    per_side = 2                               # buildings per block side
    sb = SceneBuilder()
    sb.add("ground", "ground", lambda: box((blocks * BLOCK + 40, blocks * BLOCK + 40, 0.2)),
           place((blocks * BLOCK / 2, blocks * BLOCK / 2, -0.1)))
    lot = (BLOCK - STREET) / per_side          # 15 m lots
    vase_sub = 3 if small else 4
    for bx in range(blocks):
        for by in range(blocks):
            block = sb.group(f"block_{bx}_{by}")
            for i in range(per_side):
                for j in range(per_side):
                    name = f"{block}/bldg_{i}{j}"
                    w, d = lot - rng.uniform(1.0, 3.0), lot - rng.uniform(1.0, 3.0)
                    floors = int(rng.integers(1, 3 if small else 4))
                    h = 3.2 * floors
                    cx = bx * BLOCK + STREET / 2 + (i + 0.5) * lot
                    cy = by * BLOCK + STREET / 2 + (j + 0.5) * lot
                    sb.group(name, block, place((cx, cy, 0.0)))
                    t = 0.3
                    walls = [((0, -d / 2), (w, t)), ((0, d / 2), (w, t)),
                             ((-w / 2, 0), (t, d)), ((w / 2, 0), (t, d))]
                    for k, ((x, y), (sx, sy)) in enumerate(walls):
                        sb.add(f"{name}/wall_{k}", "unit_box", box, place((x, y, h / 2), (sx, sy, h)), name)
                    sb.add(f"{name}/roof", "unit_box", box, place((0, 0, h + t / 2), (w, d, t)), name)
                    for f in range(floors):
                        for r in range(2):
                            room = sb.group(f"{name}/floor{f}_room{r}", name,
                                            place(((r - 0.5) * w / 2, 0, 3.2 * f)))
                            sb.add(f"{room}/table", "unit_box", box, place((0, 0, 0.4), (1.6, 0.9, 0.8)),
                                   room)
                            sb.add(f"{room}/vase", "vase", lambda s=vase_sub: sphere(s, 0.25),
                                   place((0.3, 0.1, 1.05)), room)
                            sb.add(f"{room}/lamp", "lamp", lambda: sphere(3, 0.3),
                                   place((rng.uniform(-1, 1), rng.uniform(-1, 1), 2.7)), room)
                            sb.add(f"{room}/bowl", "bowl", lambda: sphere(3, 0.2),
                                   place((-0.4, -0.1, 1.0), (1.0, 1.0, 0.5)), room)
    cars = 30 if small else 220
    streets = sb.group("streets")
    for c in range(cars):
        along = rng.uniform(5, blocks * BLOCK - 5)
        street = int(rng.integers(0, blocks + 1)) * BLOCK + rng.choice([-2.5, 2.5]) + 0.0
        if rng.random() < 0.5:
            xyz, rot = (along, street, 0.0), 0.0
        else:
            xyz, rot = (street, along, 0.0), np.pi / 2
        sb.add(f"streets/car_{c:03d}", "car", _car, place(xyz, rot_z=rot), streets)
    return sb.scene


def paths(small=False):
    blocks = 2 if small else 6
    size = blocks * BLOCK
    n = 90
    t = np.linspace(0.0, 1.0, n)
    # walk along the street x = 2 blocks (street centre), looking ahead, slight weave
    sx = (1 if small else 2) * BLOCK + 0.0
    eye_walk = np.stack([sx + 1.2 * np.sin(6 * t), 5 + t * (size - 10), np.full(n, 1.7)], axis=1)
    look = np.stack([sx + 3 * np.sin(2 * t + 1), eye_walk[:, 1] + 20, np.full(n, 1.6)], axis=1)
    walk = [_cam(e, g, 0.1, size * 1.5) for e, g in zip(eye_walk, look, strict=True)]
    # fly over the roofs, looking down at the city ahead
    eye_fly = np.stack([size * (0.1 + 0.8 * t), size * (0.2 + 0.3 * np.sin(3 * t)), np.full(n, 45.0)], axis=1)
    target = eye_fly + np.array([40.0, 25.0, -40.0])
    fly = [_cam(e, g, 0.5, size * 2) for e, g in zip(eye_fly, target, strict=True)]
    return {"walk": {"frames": walk}, "flyover": {"frames": fly}}


def _cam(eye, target, near, far):
    return {"eye": [float(x) for x in eye], "target": [float(x) for x in target], "up": [0.0, 0.0, 1.0],
            "fov_y_deg": 60.0, "aspect": 16 / 9, "near": near, "far": float(far), "ortho_height": None}
