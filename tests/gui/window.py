"""Blender in a real window for the GUI tests: Debian's Blender under Xvfb with a
profile of its own, the checkout loaded as a legacy add-on, this venv's moderngl,
glcontext and trimesh on its path.  Skips where that Blender's Python cannot load
this venv's compiled wheels."""

import importlib.util
import json
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ADDON = "occlusion_culled_viewport"

# Every GUI test module's marks: skipped without a windowed Blender and Xvfb.
GUI_MARKS = [
    pytest.mark.gui,
    pytest.mark.skipif(shutil.which("blender") is None or shutil.which("xvfb-run") is None,
                       reason="needs a windowed Blender and Xvfb (apt-get install blender xvfb xauth)"),
]


def blender_env(work):
    """The environment of a windowed Blender whose profile lives in ``work``."""
    cfg, scripts, site = (work / d for d in ("config", "scripts", "site"))
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
    return env


def run_in_window(env, script, args, screen="1280x720", extra=()):
    """``blender --python script -- args`` in an Xvfb window; its stdout and stderr."""
    p = subprocess.run(["xvfb-run", "-a", "-s", f"-screen 0 {screen}x24", "blender", *extra, "--python", script,
                        "--", *args], env=env, capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout + p.stderr


def window_results(work, script, args, result, **kw):
    """Run ``script`` in a window with a profile in ``work`` (``args`` may name ``{out}``, a
    folder in ``work``); -> ``(the JSON it wrote to {out}/result, its log, {out})``."""
    env, out = blender_env(work), work / "out"
    out.mkdir(exist_ok=True)
    rc, log = run_in_window(env, script, [a.format(out=out) for a in args], **kw)
    path = out / result
    assert path.exists(), f"no results (rc {rc}):\n{log[-3000:]}"
    return json.loads(path.read_text()), log, out
