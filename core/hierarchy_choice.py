"""Choosing a hierarchy by measured cost: the ``auto`` builder.

What a query, a node visit and a thousand triangles cost is measured on this
machine, with this scene uploaded (:func:`measure_costs`).  A cost model turns
those into a chunk size and decides whether a mesh is worth cutting at all
(:mod:`core.subdivision`); then every candidate builder is built and run on a
few probe frames, and the fastest is kept -- the cost of a frame is measured,
not guessed.
"""

import time

import numpy as np

from .engine import Culler

CANDIDATES = ("tree", "pHBVO", "DBVS", "octree", "balanced")
PROBE_FRAMES = 8
DEFAULT_CHUNK_TRIANGLES = 4096


def measure_costs(culler, camera):
    """Microseconds per GL query, per node visited and per thousand triangles drawn,
    measured on ``culler``'s renderer from ``camera``."""
    r = culler.renderer
    vfc = culler.cull(camera)                      # warms up; nodes_visited, frustum time
    node_us = 1e3 * vfc.stats["frustum_ms"] / max(vfc.stats["nodes_visited"], 1)
    r.begin_frame(camera)
    units = np.arange(len(culler.units))
    t = time.perf_counter()
    tris = r.draw(units)
    r.finish()
    ktri_us = 1e6 * (time.perf_counter() - t) / max(tris / 1e3, 1e-3)
    boxes = culler.hierarchy.bounds[culler.hierarchy.is_leaf][:256] - r.eye
    t = time.perf_counter()
    r.query(boxes)
    query_us = 1e6 * (time.perf_counter() - t) / max(len(boxes), 1)
    return {"query_us": query_us, "node_us": node_us, "ktri_us": ktri_us}


def chunk_size(scene, costs):
    """Chunk triangles from the cost model, or None when no mesh is worth cutting."""
    from . import subdivision as sub
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
    probe = cameras[:: max(1, len(cameras) // PROBE_FRAMES)][:PROBE_FRAMES]
    base = Culler(scene, resolution, strategy="vfc", **kw)
    try:
        costs = measure_costs(base, probe[len(probe) // 2])
    finally:
        base.close()
    chunks = chunk_triangles or chunk_size(scene, costs)
    # one culler alive at a time: probe each candidate, then rebuild the winner
    timings = {}
    for name in CANDIDATES:
        with Culler(scene, resolution, strategy=strategy, hierarchy=name,
                    chunk_triangles=None if name == "tree" else chunks, **kw) as c:
            c.cull(probe[0])
            timings[name] = float(np.median([c.cull(cam).stats["total_ms"] for cam in probe]))
    best = min(timings, key=timings.get)
    culler = Culler(scene, resolution, strategy=strategy, hierarchy=best,
                    chunk_triangles=None if best == "tree" else chunks, **kw)
    culler.costs, culler.probe_ms = costs, timings
    return culler, best + (f"/{chunks}" if chunks and best != "tree" else "")
