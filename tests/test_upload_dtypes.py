"""Geometry kept in the dtypes it comes in (float32 / int32 from Blender), and the GL
upload written block by block: the buffers hold exactly what the whole-array upload held."""

import numpy as np
import pytest

from core import Scene
from core.gl import GLRenderer, upload
from core.subdivision import build_tree
from core.units import chunked


def _meshes(rng, sizes, dtype, fdtype):
    out = []
    for nv, nf in sizes:
        v = (rng.normal(size=(nv, 3)) * 10 + rng.normal(size=3) * 1e5).astype(dtype)
        f = rng.integers(0, nv, size=(nf, 3)).astype(fdtype)
        out.append((v, f))
    return out


@pytest.mark.parametrize("dtype, fdtype", [(np.float32, np.int32), (np.float32, np.uint32),
                                           (np.float64, np.int64)])
def test_scene_keeps_dtypes_without_copy(dtype, fdtype):
    meshes = _meshes(np.random.default_rng(1), [(50, 80), (7, 5)], dtype, fdtype)
    s = Scene.from_arrays(["a", "b"], meshes, [0, 1], np.repeat(np.eye(4)[None], 2, axis=0))
    for (v, f), (sv, sf) in zip(meshes, s.meshes, strict=True):
        assert sv is v and sf is f                   # no widening copy of a whole mesh
    v = meshes[0][0]
    assert np.array_equal(s.mesh_bounds[0], np.stack([v.min(0), v.max(0)]).astype(np.float64))


def test_scene_widens_other_dtypes():
    v = np.zeros((3, 3), dtype=np.float16)
    s = Scene.from_arrays(["a"], [(v, np.array([[0, 1, 2]], dtype=np.int16))], [0], np.eye(4)[None])
    assert s.meshes[0][0].dtype == np.float64 and s.meshes[0][1].dtype == np.int64


@pytest.mark.parametrize("block", [4, 64, 1 << 16])
def test_upload_blocks_match_whole_arrays(ctx, monkeypatch, block):
    """Small meshes batched, heavy ones in blocks, a chunked one in its face order: the
    VBO and IBO read back equal the old whole-array upload (float64 recentring, then float32)."""
    monkeypatch.setattr(upload, "UPLOAD_BLOCK", block)
    monkeypatch.setattr(upload.upload_blocks, "__defaults__", (block,))
    rng = np.random.default_rng(2)
    meshes = (_meshes(rng, [(5, 3), (9, 12), (300, 900), (2, 1)], np.float32, np.int32)
              + _meshes(rng, [(40, 70)], np.float64, np.int64))
    n = len(meshes)
    s = Scene.from_arrays([str(i) for i in range(n)], meshes, np.arange(n), np.repeat(np.eye(4)[None], n, axis=0))
    units = chunked(s, lambda m, t: t > 100, lambda boxes: build_tree(boxes, "pHBVO", leaf_size=64))
    assert any(o is not None for o in units.face_order)
    r = GLRenderer(s, 8, 8, ctx=ctx, units=units)
    centres = 0.5 * (s.mesh_bounds[:, 0] + s.mesh_bounds[:, 1])
    base = np.cumsum([0] + [len(v) for v, _ in s.meshes])[:-1]
    want_v = np.concatenate([(v.astype(np.float64) - c).astype(np.float32)
                             for (v, _), c in zip(s.meshes, centres, strict=True)])
    want_i = np.concatenate([((f if o is None else f[o]).astype(np.int64) + b).astype(np.uint32).ravel()
                             for (_, f), o, b in zip(s.meshes, units.face_order, base, strict=True)])
    got_v = np.frombuffer(r.vbo.read(), dtype=np.float32).reshape(-1, 3)
    got_i = np.frombuffer(r.ibo.read(), dtype=np.uint32)
    assert np.array_equal(got_v, want_v) and np.array_equal(got_i, want_i)
    r.release()


@pytest.mark.parametrize("nv", [10, 5000])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_scene_bounds_and_invalid_meshes(nv, bad):
    """Mesh bounds per column (large meshes) or per axis (small): equal, and a NaN or
    infinite vertex makes its mesh invalid either way."""
    rng = np.random.default_rng(3)
    v = rng.normal(size=(nv, 3)).astype(np.float32)
    s = Scene.from_arrays(["a"], [(v, np.zeros((1, 3), np.int32))], [0], np.eye(4)[None])
    assert np.array_equal(s.mesh_bounds[0], np.stack([v.min(0), v.max(0)]))
    v[nv // 2, 1] = bad
    s = Scene.from_arrays(["a"], [(v, np.zeros((1, 3), np.int32))], [0], np.eye(4)[None])
    assert not s.mesh_valid[0] and s.invalid[0]
