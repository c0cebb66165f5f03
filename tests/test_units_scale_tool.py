"""tools/bench/blender_scale.py: its grid and its engine mode on a small grid (the Blender
mode needs minutes; docs/performance.md's figures come from it)."""

import json
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools", "bench"))

from blender_scale import grid_arrays  # noqa: E402


def test_grid_arrays():
    v, f = grid_arrays(10_000)
    n = 100
    assert v.shape == (n * n, 3) and f.shape == (2 * (n - 1) ** 2, 3)
    assert f.min() == 0 and f.max() == n * n - 1
    assert len(np.unique(np.sort(f, axis=1), axis=0)) == len(f)          # no triangle twice
    assert np.all(np.abs(v[:, 1:]) <= 20.0)


def test_engine_mode_reports_phases_and_no_false_negatives(tmp_path):
    out = tmp_path / "engine.json"
    p = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "bench", "blender_scale.py"), "engine",
                        "--vertices", "4000", "--chunk-triangles", "64", "--turns", "2", "--json", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    rep = json.loads(out.read_text())
    phases = [r["phase"] for r in rep["rows"]]
    assert phases[:4] == ["make_units (chunking)", "build_hierarchy", "GLRenderer (upload)", "first pass"]
    assert rep["false_negatives"] == 0 and rep["units"] > 50                  # the grid was cut into chunks
    assert all(r["seconds"] >= 0 for r in rep["rows"])


def test_engine_mode_traces_numpy_peaks(tmp_path):
    """--numpy: each engine phase's peak of traced allocations, above what was held
    before the engine; the chunking's peak holds at least its triangle boxes."""
    out = tmp_path / "engine.json"
    p = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "bench", "blender_scale.py"), "engine",
                        "--vertices", "40000", "--chunk-triangles", "256", "--turns", "1", "--numpy",
                        "--json", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "numpy peak" in p.stdout
    rep = json.loads(out.read_text())
    rows = {r["phase"]: r for r in rep["rows"]}
    chunking = rows["make_units (chunking)"]
    assert chunking["numpy_peak_MB"] >= 24 * rep["triangles"] / 2**20          # float32 boxes, 24 bytes each
    assert chunking["numpy_after_MB"] < chunking["numpy_peak_MB"]
    assert rows["first cull (all of the above)"]["numpy_peak_MB"] == max(
        r["numpy_peak_MB"] for r in rep["rows"] if "numpy_peak_MB" in r)


def test_blender_mode_steps_of_the_first_cull(tmp_path):
    """Blender mode on a small grid (real bpy, the add-on installed from its zip):
    --steps times the first cull's extraction and engine steps, each with its peak;
    the first cull's peak is the highest of its steps' and nothing is hidden wrongly."""
    out = tmp_path / "blender.json"
    p = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "bench", "blender_scale.py"), "--only", "grid",
                        "--vertices", "20000", "--turns", "1", "--steps", "--json", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    (rep,) = json.loads(out.read_text())
    rows = {r["phase"].strip(): r for r in rep["rows"]}
    steps = ["extract: scene arrays", "engine: make_units (chunking)", "engine: build_hierarchy",
             "engine: GLRenderer (upload)", "engine: pass"]
    assert all(s in rows for s in steps), list(rows)
    first = rows["first cull (extract, build, pass, hide)"]
    assert first["peak_above_MB"] >= max(rows[s]["peak_above_MB"] for s in steps)
    assert sum(rows[s]["seconds"] for s in steps) <= first["seconds"]
    assert "false negatives 0" in first["note"] and rep["false_negatives"] == 0
