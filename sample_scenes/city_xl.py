"""``city-xl``: the city tiled 3 x 3 with shared meshes -- 28,845 objects and about
41 million triangles from the city's handful of meshes -- for the scale at which
per-pass work over every node would show.  The city's own walk and flyover run
through the middle tile, with the other tiles ahead and around.

Generated on demand and cached like every sample scene, never committed (the
GLB stores each mesh once; the nine tiles are nodes).
"""

import numpy as np

from . import city

TILES = 3


def build(rng, small=False):
    import trimesh
    src = city.build(rng, small=small)
    size = (2 if small else 6) * city.BLOCK            # the city's extent along x and y
    out = trimesh.Scene()
    out.geometry.update(src.geometry)                  # shared: every tile draws the same meshes
    graph = src.graph
    base = graph.base_frame
    edges = graph.to_edgelist()
    half = TILES // 2
    for i in range(TILES):
        for j in range(TILES):
            tile = f"tile_{i}{j}"
            offset = np.eye(4)
            offset[:2, 3] = ((i - half) * size, (j - half) * size)
            out.graph.update(frame_from=out.graph.base_frame, frame_to=tile, matrix=offset)
            for a, b, attr in edges:
                kw = {"matrix": np.asarray(attr.get("matrix", np.eye(4)), dtype=np.float64)}
                if "geometry" in attr:
                    kw["geometry"] = attr["geometry"]
                out.graph.update(frame_from=tile if a == base else f"{tile}/{a}", frame_to=f"{tile}/{b}", **kw)
    return out


def paths(small=False):
    """The city's own paths (through the middle tile)."""
    return city.paths(small=small)
