"""``cathedral``: an interior where most things stay visible -- pillars, arches, pews,
walls and a roof around a nave; the walk goes down the nave."""

import numpy as np

from ._shapes import SceneBuilder, box, cylinder, place, sphere


def _arch(radius=3.0, thickness=0.5, segments=48):
    """A half ring in the XZ plane, as one mesh of boxes."""
    import trimesh
    parts = []
    for k in range(segments):                       # build time
        a = np.pi * (k + 0.5) / segments
        b = box((thickness, thickness, np.pi * radius / segments * 1.05))
        b.apply_transform(trimesh.transformations.rotation_matrix(-a, (0, 1, 0)))
        b.apply_translation((radius * np.cos(a), 0, radius * np.sin(a)))
        parts.append(b)
    return trimesh.util.concatenate(parts)


def build(rng, small=False):
    bays = 4 if small else 12
    sb = SceneBuilder()
    length = bays * 6.0
    shell = sb.group("shell")
    for k, (xyz, size) in enumerate([((length / 2, -9, 7), (length, 0.6, 14)),
                                     ((length / 2, 9, 7), (length, 0.6, 14)),
                                     ((-0.3, 0, 7), (0.6, 18, 14)), ((length + 0.3, 0, 7), (0.6, 18, 14)),
                                     ((length / 2, 0, 14.3), (length, 18, 0.6)),
                                     ((length / 2, 0, -0.1), (length, 18, 0.2))]):
        sb.add(f"{shell}/wall_{k}", "unit_box", box, place(xyz, size), shell)
    nave = sb.group("nave")
    for b in range(bays):
        x = 3.0 + 6.0 * b
        bay = sb.group(f"{nave}/bay_{b:02d}", nave, place((x, 0, 0)))
        for side in (-1, 1):
            sb.add(f"{bay}/pillar_{side:+d}", "pillar", lambda: cylinder(0.5, 9.0, 64),
                   place((0, side * 4.0, 4.5)), bay)
            sb.add(f"{bay}/capital_{side:+d}", "capital", lambda: sphere(3, 0.7),
                   place((0, side * 4.0, 9.0)), bay)
            for p in range(2):
                sb.add(f"{bay}/pew_{side:+d}_{p}", "unit_box", box,
                       place((-1.0 + 2.0 * p, side * 2.0, 0.45), (0.5, 3.0, 0.9)), bay)
        sb.add(f"{bay}/arch", "arch", lambda: _arch(4.0, 0.5, 48), place((0, 0, 9.0), rot_z=np.pi / 2),
               bay)
        sb.add(f"{bay}/chandelier", "chandelier", lambda: sphere(4, 0.6),
               place((0, 0, 11.0 + rng.uniform(-0.5, 0.5))), bay)
    sb.add("altar", "unit_box", box, place((length - 3, 0, 0.6), (2, 4, 1.2)))
    return sb.scene


def paths(small=False):
    bays = 4 if small else 12
    length = bays * 6.0
    n = 90
    t = np.linspace(0.0, 1.0, n)
    eye = np.stack([1.0 + t * (length - 6), 0.6 * np.sin(4 * t), np.full(n, 1.7)], axis=1)
    target = eye + np.stack([np.full(n, 10.0), 3 * np.sin(2 * np.pi * t), 1.5 + 2 * np.sin(3 * t)], axis=1)
    frames = [{"eye": e.tolist(), "target": g.tolist(), "up": [0, 0, 1], "fov_y_deg": 70.0,
               "aspect": 16 / 9, "near": 0.1, "far": 200.0, "ortho_height": None}
              for e, g in zip(eye, target, strict=True)]
    return {"walk": {"frames": frames}}
