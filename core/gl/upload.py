"""The scene's geometry as the renderer uploads it, block by block.

Vertices are recentred on their mesh's box centre in float64 and only then rounded
to float32 (small offsets keep float32's precision, whatever the scene's distance from
the origin); faces become absolute indices, in chunk order where a mesh is chunked.
"""

import numpy as np

from ..bounds import corners
from .layout import BOX_TRIANGLES

UPLOAD_BLOCK = 1 << 16      # rows per block of the geometry upload (~1.5 MB of float64 vertices)


def box_vertices(boxes: np.ndarray) -> np.ndarray:
    """Triangle-list vertices of boxes: ``(k, 2, 3)`` -> ``(k * 36, 3) float32``."""
    return corners(boxes)[:, BOX_TRIANGLES].reshape(-1, 3).astype(np.float32)


def upload_blocks(meshes, centres, vstart, orders, block=UPLOAD_BLOCK):
    """The vertex and index buffers' contents in order, as ``("v", (k, 3) float32)`` and
    ``("i", (j,) uint32)`` blocks of about ``block`` rows: vertices recentred on their
    mesh's centre in float64, then rounded to float32 (the precision rule: small
    offsets from the centre, whatever the data's own dtype); faces in chunk order where
    a mesh is chunked, as absolute indices.  Small meshes go in batches (a few numpy
    calls per batch, not per mesh); a heavy mesh goes block by block."""
    def batch_out(ms):
        vs = [meshes[m][0] for m in ms]
        vn = np.array([len(v) for v in vs], dtype=np.int64)
        v = np.concatenate(vs) - np.repeat(centres[ms], vn, axis=0)
        fs = [meshes[m][1] if orders[m] is None else meshes[m][1][orders[m]] for m in ms]
        fn = np.array([len(f) for f in fs], dtype=np.int64)
        f = np.concatenate(fs).astype(np.int64) + np.repeat(vstart[ms], fn)[:, None]
        return ("v", v.astype(np.float32)), ("i", f.astype(np.uint32).ravel())

    batch, rows = [], 0
    for m, (v, f) in enumerate(meshes):
        if len(v) <= block and len(f) <= block:
            batch.append(m)
            rows += max(len(v), len(f))
            if rows >= block:
                yield from batch_out(batch)
                batch, rows = [], 0
            continue
        if batch:
            yield from batch_out(batch)
            batch, rows = [], 0
        for b in range(0, len(v), block):
            yield "v", (v[b:b + block] - centres[m]).astype(np.float32)
        order = orders[m]
        for b in range(0, len(f), block):
            rows_f = f[b:b + block] if order is None else f[order[b:b + block]]
            yield "i", (rows_f.astype(np.int64) + vstart[m]).astype(np.uint32).ravel()
    if batch:
        yield from batch_out(batch)
