"""Issue 9's numbered cases in real Blender (bpy from PyPI): one test per check of
``cases.py``, which runs once in a subprocess against the zip built by Blender's
own extension CLI (see test_blender.py)."""

import os

import pytest

from .harness import ROOT, needs_bpy, run_script

CASES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cases.py")

pytestmark = needs_bpy

CHECKS = [
    *[f"case1_{w}_{c}" for w in ("eye", "collection_eye", "collection_monitor", "collection_exclude")
      for c in ("not_occluder", "truth", "user_show_wins")],
    "case2_dynamic_never_hidden", "case2_dynamic_in_view_drawn", "case2_truth",
    "case2_stale_record_given_back", "case2_stale_record_truth", "case2_restore_draws_current_frame",
    "case2_parent_animated_later", "case2_parent_animated_truth",
    *[f"case3_{t}_{c}" for t in ("small", "mirrored", "large", "nonuniform") for c in ("scale_camera", "truth")],
    "case3_mirrored_through_hole", "case3_mirrored_hole_truth",
    "case4_gn_instancer_kept", "case4_vert_instances_kept", "case4_truth",
    "case4_instances_occlude", "case4_occlude_truth", "case4_analyze_sees_instancer",
    "case4_instanced_member_kept", "case4_wire_member_instance_kept", "case4_collections_truth",
    "case4_analyze_member_seen_in_instance",
    "case5_swapped_names", "case5_swap_truth", "case5_delete_rename", "case5_delete_truth",
    "case6_occluder_moved_recull", "case6_moved_truth", "case6_never_cull_recull", "case6_undo_keeps_live",
    "case6_reload_live_true_state",
    "case7_restore_keeps_user_hide", "case7_pass_keeps_user_hide",
    "case8_still_culled_after_save", "case8_file_opens_shown_without_addon", "case8_enable_after_load_restores",
    "case8_load_restores", "case8_analyze_counts_hidden",
    "case10_wire_not_occluder", "case10_wire_truth", "case10_bounds_not_occluder", "case10_bounds_truth",
    "case10_wire_analyzed_visible", "case10_bounds_analyzed_visible",
    "case10_in_front_never_hidden", "case10_panoramic_refused", "case10_never_visible_exact",
    "case11_nan_matrix_named", "case11_nan_vertices_named", "case11_camera_scale_zero_reported",
    "case12_moved_into_exclude_drawn", "case12_undo_restore_drawn",
    "hidden_edit_move_seen", "hidden_edit_move_truth", "hidden_edit_nan_seen", "hidden_edit_nan_truth",
    "display_fast_preset_slit_kept", "display_fast_preset_truth", "display_fast_preset_closed_hidden",
    "analyze_unsaved_path_in_cwd", "analyze_background_progress",
    "steps_cancel_build_nothing_changed", "steps_cancel_build_then_cull", "steps_cancel_build_truth",
    "steps_edit_between_steps_seen", "steps_edit_between_steps_truth", "steps_analyze_cancel_restores_frame",
    "instanced_child_edited_seen", "instanced_child_edited_truth",
    "instanced_child_wire_seen", "instanced_child_wire_truth",
    "instance_source_deleted_seen", "instance_source_deleted_truth",
    "instance_member_deleted_seen", "instance_member_deleted_truth",
    "click_restarts_fresh", "click_restarts_same_answer", "click_restarts_truth",
    "instance_wire_member_analyzed_seen", "instance_bounds_member_analyzed_seen",
    "wire_instance_wire_never_hidden", "wire_instance_wire_truth",
    "wire_instance_bounds_never_hidden", "wire_instance_bounds_truth",
    "never_visible_no_path", "never_visible_excluded_everywhere",
    "rules_cycles_hides_nothing", "rules_cycles_opt_in_hides", "rules_eevee_raytracing_hides_nothing",
    "rules_xray_hides_nothing_occluded",
    "lit_eevee_no_pixel_changed", "lit_eevee_slab_shadow_shows",
    "lit_workbench_no_pixel_changed", "lit_workbench_slab_shadow_shows",
    "camera_moves_guarded_no_visible_hidden", "camera_moves_unguarded_would_hide_visible",
]


@pytest.fixture(scope="session")
def case_run(tmp_path_factory):
    return run_script(CASES, tmp_path_factory.mktemp("blender_cases"), ROOT)


def test_no_case_crashed(case_run):
    crashed = {k: v for k, v in case_run[0].items() if k.endswith("_crashed")}
    assert not crashed, crashed


def test_exit_is_quiet(case_run):
    """Case 11: a headless script that culled exits without a traceback (unregister at exit)."""
    err = case_run[1].stderr
    assert "cannot schedule new futures" not in err and "Exception in module unregister" not in err, err[-3000:]


@pytest.mark.parametrize("name", CHECKS)
def test_case(case_run, name):
    assert name in case_run[0], f"the cases never reached '{name}'"
    ok, detail = case_run[0][name]
    assert ok, detail


# Cases that once crashed Blender, each in a process of its own (see cases.ALONE).
ALONE = {"case_undo_after_collect": ["undo_after_collect_no_dangling", "undo_after_collect_keeps_last_edit",
                                     "redo_after_collect_no_dangling"]}


@pytest.mark.parametrize("case", sorted(ALONE))
def test_alone(tmp_path, case):
    """A crash shows as this case's failure (rc -11 and the output tail), not the others'."""
    results, p = run_script(CASES, tmp_path, ROOT, case)
    assert p.returncode == 0, (p.returncode, p.stderr[-3000:])
    missing = [n for n in ALONE[case] if n not in results]
    failed = {n: results[n] for n in ALONE[case] if n in results and not results[n][0]}
    assert not missing and not failed and not any(k.endswith("_crashed") for k in results), (missing, failed, results)
