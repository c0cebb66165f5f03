"""The extension in real Blender (bpy from PyPI), each check reported by one test.

The scenario runs once, in a subprocess (bpy must not share a process with the
moderngl tests), against the zip built by Blender's own extension CLI.
"""

import os

import pytest

from .harness import needs_bpy, run_script

SCENARIO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenario.py")

pytestmark = needs_bpy

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
    return run_script(SCENARIO, tmp_path_factory.mktemp("blender"))[0]


def test_scenario_did_not_crash(blender_results):
    ok, detail = blender_results.get("scenario_crashed", [True, ""])
    assert ok, detail


@pytest.mark.parametrize("name", CHECKS)
def test_check(blender_results, name):
    assert name in blender_results, f"the scenario never reached '{name}'"
    ok, detail = blender_results[name]
    assert ok, detail
