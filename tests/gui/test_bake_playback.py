"""A baked shot in a real Blender window (Debian's Blender 3.4 under Xvfb, the checkout as a
legacy add-on): Bake Shot run as a click runs it (modal, the window drawing between its
steps), then the animation played as fast as Blender draws, Use Baked Shot off and on
(``tools/bench/gui_playback.py city-small --seconds 3 --modal``).  Every sampled draw with
the bake on hides exactly the frame's baked set, in the view through the camera, and
turning the bake off shows everything; Apply to Render's keys go when a setting Blender
reports to no handler changes.  Timings are recorded, never asserted."""

import os

import pytest

from tests.gui.window import GUI_MARKS, ROOT, window_results

PLAYBACK = os.path.join(ROOT, "tools", "bench", "gui_playback.py")

pytestmark = GUI_MARKS


@pytest.fixture(scope="module")
def played(tmp_path_factory):
    results, log, _ = window_results(tmp_path_factory.mktemp("gui_bake"), PLAYBACK,
                                     ["{out}/playback.json", "city-small", "3", "1000", "modal"], "playback.json")
    return results, log


def test_modal_bake_finishes_and_stores_the_shot(played):
    r, log = played
    assert "error" not in r, r.get("error")
    assert "Traceback" not in log, log[-3000:]
    assert r["bake_modal"] and r["bake_result"] == ["RUNNING_MODAL"], r
    assert r["bake_ticks"] >= 2, r                  # the window ran between the bake's steps
    assert r["bake_stored"] and r["bake_summary"].startswith(f"frames 1-{r['frame_end']}: "), r


def test_playback_hides_exactly_each_frames_baked_set(played):
    r, _ = played
    on, off = r["bake_on"], r["bake_off"]
    assert off["hidden_max"] == 0 and off["applies"] == 0, off
    assert on["frames_advanced"] >= 2 and on["frames_applied"] > 0, on
    assert on["samples"] > 0 and on["samples_not_baked_set"] == 0, on
    assert on["hidden_max"] > 0 and on["view_perspective"] == ["CAMERA"] and on["local_view"], on
    assert on["stale"] is None and on["known"], on
    assert r["after_off"]["hidden"] == 0, r["after_off"]


def test_render_keys_go_in_the_window_when_a_setting_changes(played):
    """Apply to Render, then Include Child Collections toggled (no depsgraph update reports
    it): the window's poll removes the keys within a second."""
    k = played[0]["render_keys_poll"]
    assert k["applied"] == ["FINISHED"] and k["keyed"] and k["stood"], k
    assert k["removed"], k


def test_a_camera_view_that_draws_more_hides_no_baked_set(played):
    """The view through the camera with a clipping region (what it cuts hides nothing), then
    in Quad View (its other regions draw from other sides), then through a Local Camera, then
    with Solid's shadows on (the view's own light, which the render has not): the baked sets
    hold for the camera's picture alone, under the render's rule, so the shot hides nothing
    there, on the frame shown and the next."""
    b = played[0]["beyond_the_camera"]
    assert b["hidden_first"] > 0 and b["clip_border"] == ["FINISHED"], b
    assert b["clipped"] == b["clipped_next_frame"] == 0, b
    assert b["hidden_again"] > 0, b
    assert b["quad"] == b["quad_next_frame"] == 0, b
    # through a Local Camera of the view's own: another picture than the shot's
    assert b["one_region"] > 0 and b["local_camera"] == b["local_camera_next_frame"] == 0, b
    assert b["scene_camera_kept"], b
    # Solid's shadows turned on in the view: its own light, which the shot's render has not
    assert b["shading"] == "SOLID" and b["before_shadows"] > 0, b
    assert b["shadows"] == b["shadows_next_frame"] == 0 and b["shadows_off"] > 0, b
