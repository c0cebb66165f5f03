"""Runs the cases of ``in_blender/`` inside real Blender (bpy from PyPI), with the real
add-on installed from its zip; prints one JSON line ``OCC_RESULTS {check: [ok, detail]}``.

Every case ends with the add-on's promise checked against an independent truth
(:func:`in_blender.common.hidden_but_seen`).

Usage: python cases.py EXTENSION.zip WORKDIR REPO_ROOT [CASE,... | shard:K/N]
(the named cases only, those of ``ALONE`` run only so; or every N-th case from the K-th,
so that N processes share the cases)
"""

import json
import os
import sys
import time
import traceback

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from in_blender import analysis, bake, cameras, common, handlers, live, localview, policy, session, visibility  # noqa: E402

# In one Blender session, in this order (add-on settings a case changes stay for the next).
CASES = (policy.user_hidden_objects, policy.dynamic_objects, cameras.camera_as_rendered, policy.instancers,
         policy.collection_instances, session.identity_follows_objects, live.live_follows_changes,
         visibility.user_hide_wins, handlers.files_carry_no_hiding, policy.display_without_occluding,
         cameras.camera_panoramic_refused, analysis.never_visible_exact, policy.nan_values_named,
         cameras.camera_scale_zero_reported, cameras.camera_render_sizes, policy.exclude_collection_shown,
         session.hidden_edits, session.hidden_faces_edit, session.fast_preset_keeps_display_gaps,
         analysis.report_path_and_progress,
         session.modal_steps,
         session.instanced_child_edited, session.instance_source_deleted, session.click_restarts,
         session.engine_context_outlives_undo,
         policy.instance_wire_member_analyzed, policy.bystander_emitter_members_analyzed,
         policy.emitter_wire_instances_analyzed, policy.gn_bounds_instances_analyzed,
         policy.wire_collection_instance,
         analysis.never_visible_adds_no_path, analysis.render_leaves_out_occluders,
         analysis.never_visible_keeps_users_objects,
         policy.view_rules, policy.scene_lights, policy.see_through_materials, policy.lit_renders,
         policy.lit_renders_over_a_floor, policy.lit_renders_in_the_window_view_layer,
         policy.material_override, policy.reflection_probe, policy.jittered_lens, policy.stereo_views,
         policy.texture_alpha_workbench,
         live.camera_moves_between_ticks, live.camera_set_after_motion_holds,
         live.ortho_camera_set_holds_its_envelope, live.live_cut_is_the_engines_camera_cut,
         live.passes_land_only_unchanged,
         live.live_keeps_no_set_made_for_another_view, live.shown_again_after_an_unseen_edit,
         live.edits_show_the_set_on_screen, live.render_thread_announcements_ignored,
         localview.hides_in_one_view, localview.new_objects_drawn, localview.users_local_view,
         localview.undo_and_files, analysis.keyed_camera_composes, analysis.keyed_camera_refused,
         analysis.keyed_camera_analysis, session.bulk_map_is_its_dict,
         session.large_mesh_triangles_in_place, session.edit_outside_the_layer,
         session.edit_while_another_layer_shown, session.floor_under_the_camera,
         visibility.records_read_once_a_pass,
         localview.toggle_waits_for_engine,
         localview.failed_pass_keeps_selection, bake.bake_storage_roundtrip, bake.baked_shot_workflow,
         bake.seeded_bake_workflows, bake.baked_frames_render_unchanged,
         bake.render_baked_shot, bake.render_geometry_refused, bake.render_keys_workflow)
# Cases whose failure was a crash of Blender: each runs only when named (a process of its own).
ALONE = (analysis.undo_after_collect, session.hair_undo_two_layers, session.foreign_overrides_during_a_job)


def main():
    bpy.ops.extensions.package_install_files(filepath=common.ZIP, repo="user_default", enable_on_install=True)
    arg = sys.argv[4] if len(sys.argv) > 4 else None
    if arg is None:
        cases = CASES
    elif arg.startswith("shard:"):
        k, n = (int(x) for x in arg[len("shard:"):].split("/"))
        cases = CASES[k::n]
    else:
        cases = [c for c in CASES + ALONE if c.__name__ in arg.split(",")]
    for case in cases:
        start = time.perf_counter()
        try:
            case()
        except Exception:  # one case's crash must not hide the others' results
            common.check(f"{case.__name__}_crashed", False, traceback.format_exc())
        # each case's time, for whoever trims the suite (stderr: the results stay one line)
        print(f"OCC_CASE_TIME {case.__name__} {time.perf_counter() - start:.1f}", file=sys.stderr)


main()
print("OCC_RESULTS " + json.dumps(common.results))
