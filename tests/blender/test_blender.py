"""The extension in real Blender (bpy from PyPI), each check reported by one test.

The scenario runs once, in a subprocess (bpy must not share a process with the
moderngl tests), against the zip built by Blender's own extension CLI.
"""

import importlib.util
import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENARIO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenario.py")
PYTHON = os.environ.get("OCC_BPY_PYTHON", sys.executable)

pytestmark = [
    pytest.mark.blender,
    pytest.mark.skipif(PYTHON == sys.executable and importlib.util.find_spec("bpy") is None,
                       reason="bpy is not installed (make test installs bpy==5.0.1)"),
]

CHECKS = ["installed", "operators_registered", "panel_registered", "cull_finished", "behind_hidden",
          "wall_and_front_shown", "user_hidden_untouched", "excluded_never_hidden",
          "never_cull_respected", "instance_culled_as_unit",
          "heavy_mesh_chunked_and_hidden",
          "resized_view_keeps_chunks", "camera_untouched", "panel_figures",
          "restore_exact", "restore_keeps_user_hidden", "moved_object_reappears",
          "moved_back_hidden_again",
          "engine_kept_while_only_moving", "geometry_edit_rebuilds", "geometry_edit_back",
          "reload_restores_culled", "reload_keeps_user_hidden",
          "analyze_finished", "analyze_50_frames", "analyze_per_object", "analyze_csv",
          "analyze_leaves_scene_as_it_was", "never_visible_collection", "no_camera_reported",
          "no_viewport_reported", "live_needs_window",
          "singular_instance_culled", "empty_scene_reported", "panel_draw",
          "disable_restores"]


@pytest.fixture(scope="session")
def blender_results(tmp_path_factory):
    work = tmp_path_factory.mktemp("blender")
    dist = work / "dist"
    subprocess.run([PYTHON, os.path.join(ROOT, "tools", "build_extension.py"), "--no-wheels",
                    "--out", str(dist)], cwd=ROOT, check=True, capture_output=True, timeout=300)
    zips = sorted(dist.glob("*.zip"))
    assert len(zips) == 1, zips
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(work / "user")}
    p = subprocess.run([PYTHON, SCENARIO, str(zips[0]), str(work)], cwd=str(work), env=env,
                       capture_output=True, text=True, timeout=600)
    line = next((ln for ln in p.stdout.splitlines() if ln.startswith("OCC_RESULTS ")), None)
    assert line is not None, f"scenario printed no results (rc {p.returncode}):\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    return json.loads(line[len("OCC_RESULTS "):])


def test_scenario_did_not_crash(blender_results):
    ok, detail = blender_results.get("scenario_crashed", [True, ""])
    assert ok, detail


@pytest.mark.parametrize("name", CHECKS)
def test_check(blender_results, name):
    assert name in blender_results, f"the scenario never reached '{name}'"
    ok, detail = blender_results[name]
    assert ok, detail
