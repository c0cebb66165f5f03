"""The checks the cases inside Blender record (``cases.py``, ``in_blender/``), by the
home of the add-on whose behaviour they check; each test module reports its own."""

USER_HIDES = ("eye", "collection_eye", "collection_monitor", "collection_exclude")

CHECKS = {
    "policy": [
        *[f"user_hidden_{w}_{c}" for w in USER_HIDES for c in ("is_no_occluder", "truth", "show_wins")],
        "dynamic_never_hidden", "dynamic_in_view_drawn", "dynamic_truth",
        "dynamic_stale_record_given_back", "dynamic_stale_record_truth", "dynamic_restore_draws_current_frame",
        "dynamic_parent_animated_later", "dynamic_parent_animated_truth",
        "instancer_gn_kept", "instancer_verts_kept", "instancer_truth", "instancer_instances_occlude",
        "instancer_occlude_truth", "instancer_analyzed_seen",
        "collection_member_kept", "collection_wire_member_instance_kept", "collection_instances_truth",
        "collection_member_analyzed_seen_in_instance",
        "display_wire_is_no_occluder", "display_wire_truth", "display_bounds_is_no_occluder", "display_bounds_truth",
        "display_wire_analyzed_visible", "display_bounds_analyzed_visible", "display_in_front_never_hidden",
        "nan_matrix_named", "nan_vertices_named",
        "exclude_collection_moved_into_drawn", "exclude_collection_undo_restore_drawn",
        "instance_wire_member_analyzed_seen", "instance_bounds_member_analyzed_seen",
        "wire_instance_wire_never_hidden", "wire_instance_wire_truth",
        "wire_instance_bounds_never_hidden", "wire_instance_bounds_truth",
        "rules_cycles_hides_nothing", "rules_cycles_opt_in_hides", "rules_eevee_raytracing_hides_nothing",
        "rules_xray_hides_nothing_occluded",
        "lit_eevee_no_pixel_changed", "lit_eevee_slab_shadow_shows",
        "lit_workbench_no_pixel_changed", "lit_workbench_slab_shadow_shows",
    ],
    "cameras": [
        *[f"camera_scale_{t}_{c}" for t in ("small", "mirrored", "large", "nonuniform") for c in ("ignored", "truth")],
        "camera_mirrored_through_hole", "camera_mirrored_hole_truth",
        "camera_panoramic_refused", "camera_scale_zero_reported",
    ],
    "session": [
        "identity_swapped_names", "identity_swap_truth", "identity_delete_rename", "identity_delete_truth",
        "hidden_unedited_stays_hidden",
        "hidden_edit_move_seen", "hidden_edit_move_truth", "hidden_edit_nan_seen", "hidden_edit_nan_truth",
        "display_fast_preset_slit_kept", "display_fast_preset_truth", "display_fast_preset_closed_hidden",
        "steps_cancel_build_nothing_changed", "steps_cancel_build_then_cull", "steps_cancel_build_truth",
        "steps_edit_between_steps_seen", "steps_edit_between_steps_truth", "steps_analyze_cancel_restores_frame",
        "instanced_child_edited_seen", "instanced_child_edited_truth",
        "instanced_child_wire_seen", "instanced_child_wire_truth",
        "instance_source_deleted_seen", "instance_source_deleted_truth",
        "instance_member_deleted_seen", "instance_member_deleted_truth",
        "click_restarts_fresh", "click_restarts_same_answer", "click_restarts_truth", "bulk_map_is_its_dict",
        "large_mesh_triangles_in_place",
    ],
    "visibility": ["user_hide_kept_by_restore", "user_hide_kept_by_pass", "records_read_once_a_pass"],
    "localview": [
        "view_hides_in_its_view", "view_other_view_draws_everything", "view_visible_still_drawn",
        "view_entering_moves_nothing", "view_truth", "view_restore_leaves_view_unmoved",
        "view_selection_untouched", "view_everywhere_is_monitor",
        "view_new_object_drawn", "view_included_collection_drawn", "view_new_truth",
        "view_other_scene_shared_drawn",
        "view_user_local_culls", "view_user_local_restored", "view_user_local_undo_to_culled_draws",
        "view_user_leaves_local_record_ends",
        "view_undo_keeps_visible_drawn", "view_save_keeps_culled", "view_saved_file_opens_drawn",
        "view_saved_file_without_hiding_opens_plain", "view_operator_waits_for_engine",
        "view_failed_pass_keeps_selection",
    ],
    "handlers": ["save_keeps_culled", "saved_file_opens_shown_without_addon", "old_file_restored_on_enable",
                 "old_file_restored_on_load"],
    "live": [
        "live_occluder_moved_reculls", "live_moved_truth", "live_never_cull_reculls", "live_settings_reculls",
        "live_survives_undo",
        "live_reload_flag_matches_timer",
        "camera_moves_guarded_no_visible_hidden", "camera_moves_unguarded_would_hide_visible",
        "live_cut_is_the_engines_camera_cut",
    ],
    "analysis": [
        "analyze_counts_hidden", "never_visible_exact", "analyze_unsaved_path_in_cwd",
        "analyze_background_progress", "never_visible_no_path", "never_visible_excluded_everywhere",
        "analyze_chunks_merge_to_whole",
        *[f"never_visible_route_{r}_kept" for r in ("move", "add_active", "script_duplicate")],
        "never_visible_routes_nothing_lost", "never_visible_routes_saved_and_opened",
        "never_visible_routes_users_link_kept_ours_unlinked",
        *[f"keyed_camera_composes_{m}" for m in ("xyz", "zxy", "quaternion", "axis_angle")],
        "keyed_camera_taken", "keyed_camera_refused", "keyed_camera_report_is_frames_report",
        "keyed_camera_moving_scene_frames",
    ],
}

# Cases that once crashed Blender, each in a process of its own (see cases.ALONE): case -> its checks.
ALONE = {"undo_after_collect": ["undo_after_collect_no_dangling", "undo_after_collect_keeps_last_edit",
                                "redo_after_collect_no_dangling"]}
