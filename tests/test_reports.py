"""The report folder: every file explained, pictures with legends, a noise-aware Pareto front."""

import json
import os
import subprocess
import sys

import numpy as np

from core import Culler
from core.lab.reports import _RecordingMap, _watched_occupancy_map
from core.lab.tradeoff import pareto, plot_tradeoff, run_tradeoff
from tests import scenes
from tests.cli_helpers import ROOT


def test_bench_report_folder_has_an_index_of_every_file(tmp_path):
    import trimesh
    s = trimesh.Scene()
    for i in range(12):
        s.add_geometry(trimesh.creation.box((1, 1, 2)), node_name=f"b{i}", geom_name="box",
                       transform=trimesh.transformations.translation_matrix((3 * i, 0, 0)))
    s.export(tmp_path / "row.glb")
    (tmp_path / "path.json").write_text(json.dumps({"frames": [{"eye": [-5, 0.3 * k, 1], "target": [10, 0, 1]}
                                                               for k in range(4)]}))
    out = tmp_path / "reports"
    p = subprocess.run([sys.executable, "-m", "core", "bench", str(tmp_path / "row.glb"), "--camera",
                        str(tmp_path / "path.json"), "--strategies", "vfc,om_multi", "--resolution", "64x48",
                        "--plot", "--snapshot", "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    files = sorted(os.listdir(out))
    assert files == sorted(["README.txt", "row.json", "row.txt", "row_frame_ms.png", "row_triangles.png",
                            "row_view.png", "row_occluded_xray.png", "row_occupancy.png"])
    index = (out / "README.txt").read_text()
    for name in files:
        if name != "README.txt":
            line = next(ln for ln in index.splitlines() if ln.strip().startswith(name))
            assert "not written by this tool" not in line, line
    assert "== row ==" in index                     # the table follows the list
    assert all((out / f).stat().st_size > 1000 for f in files if f.endswith(".png"))


def test_occupancy_map_is_watched_through_the_pass(ctx):
    """The occupancy picture shows when tiles were covered: the engine's pass must build its
    map where the report can watch it, and every covered tile has a time."""
    scene, cams, _ = scenes.random_city(3, 200)
    cam = cams[0]
    with Culler(scene, (96, 64), strategy="om_multi") as c, _watched_occupancy_map():
        result = c.cull(cam)
    om = _RecordingMap.last
    assert om is not None and om.sets > 0 and om.asks > 0
    assert np.array_equal(om.first_set >= 0, result.occupancy)


def test_pareto_accounts_for_noise():
    # no spread: the plain front (a faster point with as few misses wins)
    assert pareto([(10, 0), (11, 0)]).tolist() == [0]
    # 10 +- 2 and 11 +- 2 overlap: a tie on time, both stay
    assert pareto([(10, 0), (11, 0)], [2, 2]).tolist() == [0, 1]
    # overlapping times, but one misses fewer pixels: it wins
    assert pareto([(10, 5), (11, 0)], [2, 2]).tolist() == [1]
    # spreads apart: the faster one wins
    assert pareto([(5, 0), (11, 0)], [1, 1]).tolist() == [0]


def test_tradeoff_front_includes_presets_and_axis_never_negative(ctx, tmp_path):
    scene, cams, _ = scenes.random_city(9, 120)
    rep = run_tradeoff(scene, cams[:2], (96, 64), knobs=(), log=lambda *a: None, repeats=2)
    assert rep["pareto"] and all(label.startswith("preset=") for label in rep["pareto"])
    for r in rep["presets"].values():
        assert len(r["frame_ms_repeats"]) == 2 and r["frame_ms_spread"] >= 0
    rep["knobs"] = {}
    for r in rep["presets"].values():           # nothing missed anywhere
        r["pixels_missed_per_frame"] = 0.0
    low, high = plot_tradeoff(rep, str(tmp_path / "t.png"), "t")
    assert low == 0.0 and high > 0 and (tmp_path / "t.png").exists()
