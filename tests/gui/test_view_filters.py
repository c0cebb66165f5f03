"""What a 3D view does not draw never occludes what it draws: local view and the
viewport's object-type filters, in a real window (Debian's Blender 3.4 under
Xvfb, the add-on loaded as a legacy add-on from this checkout), through the Cull
operator in the view and through live mode's timer (whose context has no 3D
view).  ``view_filters.py`` drives Blender; see it for the scenes.

Skipped where ``blender`` or ``xvfb-run`` is missing or where that Blender's
Python cannot load this venv's moderngl wheel.
"""

import importlib.util
import json
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DRIVER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "view_filters.py")
ADDON = "occlusion_culled_viewport"

pytestmark = [
    pytest.mark.gui,
    pytest.mark.skipif(shutil.which("blender") is None or shutil.which("xvfb-run") is None,
                       reason="needs a windowed Blender and Xvfb (apt-get install blender xvfb xauth)"),
]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    work = tmp_path_factory.mktemp("view_filters")
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
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-expr",
                        "import sys; print('PYVER %d.%d' % sys.version_info[:2])"],
                       env=env, capture_output=True, text=True, timeout=120)
    version = next((ln[6:] for ln in p.stdout.splitlines() if ln.startswith("PYVER ")), "")
    here = "%d.%d" % sys.version_info[:2]
    if version != here:
        pytest.skip(f"Blender's Python is {version or 'unknown'}, this venv's moderngl is built for {here}")
    subprocess.run(["blender", "-b", "--factory-startup", "--python-expr",
                    "import bpy; bpy.context.preferences.view.show_splash = False; bpy.ops.wm.save_userpref()"],
                   env=env, check=True, capture_output=True, timeout=120)
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x720x24", "blender", "--python", DRIVER,
                        "--", str(out)], env=env, capture_output=True, text=True, timeout=600)
    log = p.stdout + p.stderr
    path = out / "view_filters.json"
    assert path.exists(), f"no results (rc {p.returncode}):\n{log[-3000:]}"
    res = json.loads(path.read_text())
    assert "error" not in res, res["error"]
    assert "Traceback" not in log, log[-3000:]
    return res


def test_the_wall_hides_the_box_when_both_are_drawn(results):
    for name in ("full", "type_filter_sanity"):
        assert results[name] == {"cull_result": ["FINISHED"], "operator": True, "live": True}, (name, results)


def test_a_wall_out_of_local_view_hides_nothing(results):
    assert results["local_view"] == {"cull_result": ["FINISHED"], "operator": False, "live": False}, results


def test_a_wall_the_type_filter_hides_hides_nothing(results):
    assert results["type_filter"] == {"cull_result": ["FINISHED"], "operator": False, "live": False}, results


def test_an_object_the_addon_hid_out_of_local_view_hides_nothing(results):
    r = results["hidden_out_of_local_view"]
    assert r["operator_first_pass_hid_the_cube"] and r["live_first_pass_hid_the_cube"], r
    assert (r["operator"], r["live"]) == (False, False), r


def test_a_wall_filtered_out_after_a_pass_gives_back_what_it_hid(results):
    r = results["filter_toggled_after_pass"]
    assert r["operator_hid_first"] and r["live_hid_first"], r
    assert (r["operator"], r["live"]) == (False, False), r
