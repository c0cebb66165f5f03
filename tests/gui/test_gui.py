"""The add-on in a real Blender window: Debian's Blender 3.4 under Xvfb, loaded
as a legacy add-on from this checkout, driven by ``tools/gui_benchmark.py`` on
the small city (one cull through the real operator, the real panel and overlay
drawn, live passes, redraws timed).  Timings are recorded, never asserted.

Skipped where ``blender`` or ``xvfb-run`` is missing (``.ci/run`` installs
them) or where that Blender's Python cannot load this venv's moderngl wheel.
"""

import importlib.util
import json
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BENCH = os.path.join(ROOT, "tools", "gui_benchmark.py")
ADDON = "occlusion_culled_viewport"

pytestmark = [
    pytest.mark.gui,
    pytest.mark.skipif(shutil.which("blender") is None or shutil.which("xvfb-run") is None,
                       reason="needs a windowed Blender and Xvfb (apt-get install blender xvfb xauth)"),
]


def _blender_python(env):
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-expr",
                        "import sys; print('PYVER %d.%d' % sys.version_info[:2])"],
                       env=env, capture_output=True, text=True, timeout=120)
    line = next((ln for ln in p.stdout.splitlines() if ln.startswith("PYVER ")), "")
    return line[6:]


@pytest.fixture(scope="module")
def gui_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("gui")
    cfg, scripts, site, out = (work / d for d in ("config", "scripts", "site", "out"))
    for d in (cfg, scripts / "addons", site):
        d.mkdir(parents=True)
    os.symlink(ROOT, scripts / "addons" / ADDON)            # the checkout as a legacy add-on
    for mod in ("moderngl", "glcontext", "trimesh"):         # this venv's packages, for Blender's Python
        origin = os.path.dirname(importlib.util.find_spec(mod).origin)
        os.symlink(origin, site / mod)
    os.symlink(importlib.util.find_spec("_moderngl").origin, site / "_moderngl.py")
    env = {**os.environ, "BLENDER_USER_CONFIG": str(cfg), "BLENDER_USER_SCRIPTS": str(scripts),
           "PYTHONPATH": f"{site}{os.pathsep}{ROOT}"}
    version = _blender_python(env)
    here = "%d.%d" % sys.version_info[:2]
    if version != here:
        pytest.skip(f"Blender's Python is {version or 'unknown'}, this venv's moderngl is built for {here}")
    subprocess.run(["blender", "-b", "--factory-startup", "--python-expr",
                    "import bpy; bpy.context.preferences.view.show_splash = False; bpy.ops.wm.save_userpref()"],
                   env=env, check=True, capture_output=True, timeout=120)
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1600x900x24", "blender", "--enable-event-simulate",
                        "--python", BENCH, "--", str(out), "city-small"],
                       env=env, capture_output=True, text=True, timeout=600)
    log = p.stdout + p.stderr
    path = out / "gui.json"
    assert path.exists(), f"no results (rc {p.returncode}):\n{log[-3000:]}"
    return json.loads(path.read_text()), log, out


def test_run_finished_without_errors(gui_run):
    results, log, _ = gui_run
    assert "error" not in results, results.get("error")
    assert "Traceback" not in log, log[-3000:]          # panel and overlay draw errors land here


def test_cull_operator_hid_occluded_objects(gui_run):
    results, _, _ = gui_run
    assert results["cull_result"] == ["FINISHED"]
    assert results["tested"] == results["objects"]
    assert results["occluded"] > 0 and 0 < results["triangles_hidden"] < results["triangles"]


def test_live_passes_reuse_the_engine(gui_run):
    results, _, _ = gui_run
    assert len(results["live_pass_ms"]) == 10
    assert results["engine_rebuilt_during_live_passes"] is False


def test_live_hidden_set_holds_while_the_view_turns(gui_run):
    """After every redraw of a turning view, what live mode hides holds for that view
    (inside its envelope) or nothing is hidden; passes are made during the motion."""
    results, _, _ = gui_run
    motion = results["live_motion"]
    assert motion["rested_with_envelope"], motion
    assert all(motion["held"]) and len(motion["held"]) == 12, motion
    assert motion["passes"] >= 1, motion


def test_redraws_timed_and_screenshots_written(gui_run):
    results, _, out = gui_run
    for key in ("redraw_ms_without", "redraw_ms_with", "redraw_ms_restored", "redraw_ms_nothing_drawn"):
        assert results[key] > 0, key
    before, culled = (out / "before.png").read_bytes(), (out / "culled.png").read_bytes()
    assert before[:8] == culled[:8] == b"\x89PNG\r\n\x1a\n" and before != culled


def test_modal_cull_builds_in_steps_and_matches_the_pass_at_once(gui_run):
    results, _, _ = gui_run
    assert results["modal_cull_started"] == ["RUNNING_MODAL"]
    modal, sync = results["modal_cull"], results["sync_cull"]
    assert modal["finished"], modal
    assert (modal["occluded"], modal["outside"]) == (sync["occluded"], sync["outside"]), (modal, sync)


def test_modal_analyze_esc_leaves_the_scene_as_it_was(gui_run):
    results, _, _ = gui_run
    assert results["modal_analyze_started"] == ["RUNNING_MODAL"]
    assert results["modal_analyze_esc"] == {"busy": None, "frame": 3, "written": False}
    assert results["modal_analyze_done"] == {"busy": None, "frame": 3, "written": True}
