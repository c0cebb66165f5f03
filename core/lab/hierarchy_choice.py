"""Choosing a hierarchy by measured cost: the ``auto`` builder.

What a query, a node visit and a thousand triangles cost is measured on this
machine, with this scene uploaded (:func:`measure_costs`).  A cost model turns
those into a chunk size and decides whether a mesh is worth cutting at all
(:mod:`core.subdivision`); then every candidate builder is built and run on a
few probe frames, and the fastest is kept -- the cost of a frame is measured,
not guessed.  For meshes worth cutting, the model's chunk size and 4x and 16x
coarser ones are probed on pHBVO (per-node Python overhead makes the model's
size a lower bound), and the other builders use the best.
"""

import time

import numpy as np

from ..engine import Culler
from .jobs import spread

CANDIDATES = ("tree", "pHBVO", "DBVS", "octree", "balanced")
PROBE_FRAMES = 8
DEFAULT_CHUNK_TRIANGLES = 4096
NODE_US_DEFAULT = 1.0        # measured on the city: 0.9 ms frustum culling for ~1,450 nodes


def measure_costs(culler, camera):
    """Microseconds per GL query, per node visited and per thousand triangles drawn,
    measured on ``culler``'s renderer from ``camera``."""
    r = culler.renderer
    vfc = culler.cull(camera)                      # warms up; nodes_visited, frustum time
    # per node, once there are enough nodes that the pass's fixed cost does not dominate
    nodes = vfc.stats.nodes_visited
    node_us = 1e3 * vfc.stats.frustum_ms / nodes if nodes >= 256 else NODE_US_DEFAULT
    r.begin_frame(camera)
    units = np.arange(len(culler.units))
    t = time.perf_counter()
    tris = r.draw(units)
    r.finish()
    ktri_us = 1e6 * (time.perf_counter() - t) / max(tris / 1e3, 1e-3)
    # queries of chunk-sized boxes (1/32 of the scene) spread over the scene
    lo, hi = culler.hierarchy.bounds[0]
    size = (hi - lo) / 32.0
    corner = lo + np.random.default_rng(0).random((256, 3)) * (hi - lo - size)
    boxes = np.stack([corner, corner + size], axis=1) - r.eye
    r.begin_frame(camera)
    t = time.perf_counter()
    r.query(boxes)
    query_us = 1e6 * (time.perf_counter() - t) / len(boxes)
    return {"query_us": query_us, "node_us": node_us, "ktri_us": ktri_us}


def chunk_size(scene, costs):
    """Chunk triangles from the cost model, or None when no mesh is worth cutting."""
    from .. import subdivision as sub
    tri = np.array([len(f) for _, f in scene.meshes])
    heavy = [t for t in tri if sub.worth_chunking(int(t), costs["query_us"], costs["ktri_us"])]
    if not heavy:
        return None
    return int(sub.choose_leaf_size(int(np.median(heavy)), costs["query_us"], costs["node_us"],
                                    costs["ktri_us"]))


def build_culler(scene, resolution, strategy, builder, cameras, chunk_triangles=None, **kw):
    """A Culler with hierarchy ``builder`` (or the measured best for ``"auto"``).

    Returns ``(culler, chosen builder name)``; the caller closes the culler.
    """
    if builder != "auto":
        chunks = None if builder == "tree" else (chunk_triangles or DEFAULT_CHUNK_TRIANGLES)
        return Culler(scene, resolution, strategy=strategy, hierarchy=builder,
                      chunk_triangles=chunks, **kw), builder
    probe = spread(cameras, PROBE_FRAMES)
    base = Culler(scene, resolution, strategy="vfc", **kw)
    try:
        costs = measure_costs(base, probe[len(probe) // 2])
    finally:
        base.close()
    model = chunk_triangles or chunk_size(scene, costs)
    # one culler alive at a time: probe each candidate, then rebuild the winner
    timings = {}

    def probe_ms(name, chunks):
        with Culler(scene, resolution, strategy=strategy, hierarchy=name,
                    chunk_triangles=None if name == "tree" else chunks, **kw) as c:
            c.cull(probe[0])
            return float(np.median([c.cull(cam).stats.total_ms for cam in probe]))

    chunks = model
    if model and not chunk_triangles:          # the model's size and 4x, 16x coarser, on pHBVO
        sizes = sorted({model, 4 * model, 16 * model})
        by_size = {k: probe_ms("pHBVO", k) for k in sizes}
        chunks = min(by_size, key=by_size.get)
        timings["pHBVO"] = by_size[chunks]
    for name in CANDIDATES:
        if name not in timings:
            timings[name] = probe_ms(name, chunks)
    best = min(timings, key=timings.get)
    culler = Culler(scene, resolution, strategy=strategy, hierarchy=best,
                    chunk_triangles=None if best == "tree" else chunks, **kw)
    culler.costs, culler.probe_ms = costs, timings
    return culler, best + (f"/{chunks}" if chunks and best != "tree" else "")
