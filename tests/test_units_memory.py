"""Memory of the chunking of one heavy mesh (core.units, core.subdivision): the same
chunks as the whole-array implementation it replaced (argsort partitions, float32
vertex copies), and a peak bounded by a ratio of the triangle boxes' own size,
measured with tracemalloc (numpy reports its allocations there)."""

import tracemalloc

import numpy as np
import pytest

import core.subdivision as sd
import core.units as units
from core import Scene
from core.engine import make_units
from core.units import triangle_bounds


def grid_mesh(n, dtype=np.float32, seed=0):
    """An n x n vertex grid with relief, its triangles shuffled: ``(n*n, 3)``, ``(f, 3) int32``."""
    t = np.linspace(-5.0, 5.0, n)
    v = np.zeros((n * n, 3))
    v[:, 0], v[:, 1] = np.repeat(t, n), np.tile(t, n)
    v[:, 2] = 0.3 * np.sin(v[:, 0] * 1.7) * np.cos(v[:, 1])
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    f = np.concatenate([np.stack([q, q + 1, q + n + 1], 1), np.stack([q, q + n + 1, q + n], 1)])
    f = f[np.random.default_rng(seed).permutation(len(f))]
    return v.astype(dtype), f.astype(np.int32)


# --- the implementations replaced, as references -------------------------------------
def reference_triangle_bounds(vertices, faces):
    """Outward-rounded float32 boxes from the float64 triangles ``(f, 3, 3)`` at once."""
    tri = np.asarray(vertices, dtype=np.float64)[faces]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    lo32, hi32 = lo.astype(np.float32), hi.astype(np.float32)
    lo32 = np.where(lo32.astype(np.float64) > lo, np.nextafter(lo32, np.float32(-np.inf)), lo32)
    hi32 = np.where(hi32.astype(np.float64) < hi, np.nextafter(hi32, np.float32(np.inf)), hi32)
    return np.ascontiguousarray(lo32.T), np.ascontiguousarray(hi32.T)


def reference_partition(self, s, e, labels, parts=None):
    """The partition as it was: a whole-range stable argsort, one take per row."""
    if callable(labels):
        labels = labels(0, e - s)                                 # the labels of the range at once
    order = np.argsort(labels, kind="stable")
    for r in self.rows:
        seg = r[s:e]
        seg[...] = seg[order]
    return np.bincount(labels) if labels.dtype != bool else np.bincount(labels, minlength=2)


def chunks(scene, builder, leaf):
    u = make_units(scene, builder, chunk_triangles=leaf, chunk_min_triangles=1)
    return u.face_order[0], u.first, u.count, u.local_bounds


@pytest.mark.parametrize("n", [1, 7, 1000, 5001])
def test_labelled_partition_is_the_stable_argsort(n, monkeypatch):
    """The blocked counting sort moves every row as a stable argsort of the labels
    would, and counts the parts."""
    monkeypatch.setattr(sd, "PARTITION_BLOCK", 64)
    monkeypatch.setattr(sd, "COMPRESS_ITEMS", 0)                    # two-way splits by blocks too
    rng = np.random.default_rng(n)
    for parts in (1, 2, 8, 16):
        for labels in (rng.integers(0, parts, n).astype(np.uint8),
                       np.repeat(rng.integers(0, parts, n // 7 + 1), 7)[:n].astype(np.uint8)):
            rows = [np.arange(n + 9, dtype=np.int32), rng.random(n + 9).astype(np.float32)]
            want = [r.copy() for r in rows]
            counts = sd._Partitioner(rows)(4, 4 + n, labels)
            for r, w in zip(rows, want, strict=True):
                w[4:4 + n] = w[4:4 + n][np.argsort(labels, kind="stable")]
                assert np.array_equal(r, w)
            assert np.array_equal(counts, np.bincount(labels))
            if parts == 2:
                counts = sd._Partitioner(rows)(4, 4 + n, labels.astype(bool))
                assert np.array_equal(counts, np.bincount(labels, minlength=2))
            # labels made block by block by a function (pHBVO's planned levels)
            rows = [np.arange(n, dtype=np.int32)]
            asked = []

            def label_of(a, b, lab=labels, seen=asked):
                seen.append(b - a)
                return lab[a:b]

            counts = sd._Partitioner(rows)(0, n, label_of, parts)
            assert np.array_equal(rows[0], np.argsort(labels, kind="stable"))
            assert np.array_equal(counts, np.bincount(labels, minlength=parts))
            assert max(asked) <= 64 and sum(asked) == n                  # never the whole range at once


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_triangle_bounds_match_the_float64_triangles(dtype, monkeypatch):
    """Blocked bounds, gathered straight from float32 vertices or through outward
    copies of float64 ones, equal the float64 triangles' boxes rounded outward."""
    monkeypatch.setattr(units, "BLOCK", 100)
    rng = np.random.default_rng(3)
    v = (rng.normal(0.0, 10.0, (700, 3)) + 1e4).astype(dtype)
    f = rng.integers(0, 700, (2500, 3)).astype(np.int32)
    lo, hi = triangle_bounds(v, f)
    ref_lo, ref_hi = reference_triangle_bounds(v, f)
    assert np.array_equal(lo, ref_lo) and np.array_equal(hi, ref_hi)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("builder", ["tree", "DBVS", "octree", "balanced"])
def test_chunking_is_the_one_of_the_whole_array_implementation(seed, builder, monkeypatch):
    """Blocked partitions and bounds cut a mesh into the very chunks (face order,
    ranges, boxes) that the whole-array argsort partition and float64 bounds give;
    PLAN_ITEMS lowered so that pHBVO's planned levels (uint8 partitions) run, and
    COMPRESS_ITEMS so that two-way splits take both of their paths."""
    v, f = grid_mesh(60, dtype=[np.float32, np.float64][seed % 2], seed=seed)
    scene = Scene.from_arrays(["a", "b"], [(v, f)], [0, 0], [np.eye(4)] * 2)
    monkeypatch.setattr(sd, "PLAN_ITEMS", 1500)
    monkeypatch.setattr(sd, "PARTITION_BLOCK", 333)
    monkeypatch.setattr(sd, "COMPRESS_ITEMS", [100, 10**9][seed // 2])   # two-way splits by order, or compressed
    monkeypatch.setattr(units, "BLOCK", 500)
    new = chunks(scene, builder, 32)
    monkeypatch.setattr(sd._Partitioner, "__call__", reference_partition)
    monkeypatch.setattr(units, "triangle_bounds", reference_triangle_bounds)
    old = chunks(scene, builder, 32)
    for a, b in zip(new, old, strict=True):
        assert np.array_equal(a, b)
    assert len(new[1]) > 50                                       # cut into many chunks


def test_chunking_peak_is_a_bounded_multiple_of_the_triangle_boxes(monkeypatch):
    """Peak traced memory of chunking one float32 mesh (1,276,802 triangles, blocks made
    small as at 20 M triangles, pHBVO's planned levels on): at most 1.65 x the float32
    triangle boxes (24 bytes a triangle).  The boxes, the int32 item order, one scratch
    row, a partition's labels and uint16 block orders make ~1.46 (measured 1.46 at
    20 M triangles, 1.57 here with the tree's fixed costs and a plan's sample, about
    300 bytes a sample item: at 318,402 triangles those weigh 0.25 more); the
    whole-array argsort partitions and float32 vertex copies that this replaced made
    2.25, the plans of a whole wave of nodes together 2.1."""
    monkeypatch.setattr(units, "BLOCK", 1 << 14)
    monkeypatch.setattr(sd, "PARTITION_BLOCK", 1 << 14)
    v, f = grid_mesh(800)
    scene = Scene.from_arrays(["g"], [(v, f)], [0], [np.eye(4)])
    assert len(f) > sd.PLAN_ITEMS                                # the planned path runs
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        u = make_units(scene, "tree", 256)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert len(u) > 500
    assert peak <= 1.65 * 24 * len(f), peak / (24 * len(f))


def test_float32_vertices_are_not_copied(monkeypatch):
    """Bounds of a few triangles over many float32 vertices allocate about their
    output, not a copy of the vertices."""
    rng = np.random.default_rng(4)
    v = rng.normal(size=(200_000, 3)).astype(np.float32)           # 2.4 MB
    f = rng.integers(0, len(v), (5000, 3)).astype(np.int32)        # boxes: 120 kB
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        triangle_bounds(v, f)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert peak < v.nbytes / 4, peak                               # vertex copies: 2 x 2.4 MB
