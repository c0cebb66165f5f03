"""Shared by the Blender checks: build the extension zip as users do and run a script
inside real Blender (``bpy`` from PyPI) in its own process, with an isolated user folder
(bpy must not share a process with the moderngl tests)."""

import importlib.util
import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PYTHON = os.environ.get("OCC_BPY_PYTHON", sys.executable)
CASES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cases.py")    # the cases inside Blender

needs_bpy = [
    pytest.mark.blender,
    pytest.mark.skipif(PYTHON == sys.executable and importlib.util.find_spec("bpy") is None,
                       reason="bpy is not installed (make test installs bpy==5.0.1)"),
]


def build_zip(work):
    """The extension zip (no wheels: the venv's moderngl serves) built into ``work/dist``."""
    dist = work / "dist"
    subprocess.run([PYTHON, os.path.join(ROOT, "tools", "build_extension.py"), "--no-wheels",
                    "--out", str(dist)], cwd=ROOT, check=True, capture_output=True, timeout=300)
    zips = sorted(dist.glob("*.zip"))
    assert len(zips) == 1, zips
    return zips[0]


def run_script(script, work, *args, timeout=600):
    """Run ``script ZIP WORK *args`` in Blender; returns (the JSON of its ``OCC_RESULTS``
    line, the completed process)."""
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(work / "user")}
    p = subprocess.run([PYTHON, script, str(build_zip(work)), str(work), *args], cwd=str(work), env=env,
                       capture_output=True, text=True, timeout=timeout)
    line = next((ln for ln in p.stdout.splitlines() if ln.startswith("OCC_RESULTS ")), None)
    assert line is not None, (f"{os.path.basename(script)} printed no results (rc {p.returncode}):\n"
                              f"{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
    return json.loads(line[len("OCC_RESULTS "):]), p


def assert_check(results, name):
    """One check a script recorded: reached, and passed (its detail says why not)."""
    assert name in results, f"the script never reached '{name}'"
    ok, detail = results[name]
    assert ok, detail
