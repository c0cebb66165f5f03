"""``assembly``: CAD-like parts -- gears, boards, screws, cables -- inside closed and
cut-away casings (the casing's front plate is missing on every other unit)."""

import numpy as np

from ._shapes import SceneBuilder, box, cylinder, gear, place, sweep


def build(rng, small=False):
    units = 2 if small else 4
    parts_per = 30 if small else 80
    sb = SceneBuilder()
    for u in range(units):
        ux = u * 3.0
        unit = sb.group(f"unit_{u}", None, place((ux, 0.0, 0.0)))
        cut = u % 2 == 1                                    # cut-away: no front plate
        plates = [((0, 0, -0.6), (2.4, 1.6, 0.05)), ((0, 0, 0.6), (2.4, 1.6, 0.05)),
                  ((-1.2, 0, 0), (0.05, 1.6, 1.2)), ((1.2, 0, 0), (0.05, 1.6, 1.2)),
                  ((0, 0.8, 0), (2.4, 0.05, 1.2))] + ([] if cut else [((0, -0.8, 0), (2.4, 0.05, 1.2))])
        casing = sb.group(f"{unit}/casing", unit)
        for k, (xyz, size) in enumerate(plates):
            sb.add(f"{casing}/plate_{k}", "unit_box", box, place(xyz, size), casing)
        inner = sb.group(f"{unit}/parts", unit)
        for p in range(parts_per):
            kind = p % 4
            xyz = rng.uniform([-1.0, -0.6, -0.45], [1.0, 0.6, 0.45])
            name = f"{inner}/part_{p:03d}"
            if kind == 0:
                r = rng.choice([0.1, 0.15, 0.2])
                sb.add(name + "_gear", f"gear_{r}", lambda r=r: gear(r, 0.04, 18, 96),
                       place(xyz, rot_z=rng.uniform(0, np.pi)), inner)
            elif kind == 1:
                sb.add(name + "_board", "unit_box", box,
                       place(xyz, (rng.uniform(0.2, 0.6), rng.uniform(0.2, 0.5), 0.015)), inner)
            elif kind == 2:
                sb.add(name + "_screw", "screw", lambda: cylinder(0.01, 0.08, 24),
                       place(xyz, rot_z=rng.uniform(0, np.pi)), inner)
            else:
                pts = xyz + np.cumsum(rng.normal(scale=0.08, size=(24, 3)), axis=0)
                pts = np.clip(pts, [-1.1, -0.7, -0.55], [1.1, 0.7, 0.55])
                geom = f"cable_{u}_{p}"
                sb.add(name + "_cable", geom, lambda pts=pts: sweep(pts, 0.012, 16), None, inner)
    return sb.scene


def paths(small=False):
    units = 2 if small else 4
    centre = np.array([(units - 1) * 1.5, 0.0, 0.0])
    n = 90
    t = np.linspace(0.0, 1.0, n)
    angle = -np.pi / 2 + 1.5 * np.pi * t                 # starts in front of the casings
    radius = (3.0 + 1.5 * units) * (1.0 - 0.75 * t)      # zooms in towards the parts
    eye = centre + np.stack([radius * np.cos(angle), radius * np.sin(angle), 0.8 + 0.5 * np.sin(3 * t)],
                            axis=1)
    frames = [{"eye": e.tolist(), "target": centre.tolist(), "up": [0, 0, 1], "fov_y_deg": 50.0,
               "aspect": 16 / 9, "near": 0.02, "far": 100.0, "ortho_height": None} for e in eye]
    return {"orbit": {"frames": frames}}
