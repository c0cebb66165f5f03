"""The extension zips as a user gets them: one per platform, each with its own wheels.

The wheels here are stand-ins with the real file names (no network in tests); the zips are
built by tools/build_extension.py's own writer (what `make extension` uses without Blender)
and by Blender's extension CLI from the bpy module, and must be the same and valid.
"""

import ast
import glob
import importlib.util
import os
import re
import subprocess
import sys
import tomllib
import zipfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.join(ROOT, "tools", "build_extension.py")
# the wheels `pip download` chose for moderngl 5.13 / glcontext 3.1 (macOS x64 stops at 5.12 / 3.0)
WHEELS = [
    "glcontext-3.0.0-cp311-cp311-macosx_10_9_x86_64.whl",
    "glcontext-3.0.0-cp313-cp313-macosx_10_13_x86_64.whl",
    "glcontext-3.1.0-cp311-cp311-macosx_11_0_arm64.whl",
    "glcontext-3.1.0-cp311-cp311-manylinux1_x86_64.manylinux_2_28_x86_64.manylinux_2_5_x86_64.whl",
    "glcontext-3.1.0-cp311-cp311-win_amd64.whl",
    "glcontext-3.1.0-cp313-cp313-macosx_11_0_arm64.whl",
    "glcontext-3.1.0-cp313-cp313-manylinux1_x86_64.manylinux_2_28_x86_64.manylinux_2_5_x86_64.whl",
    "glcontext-3.1.0-cp313-cp313-win_amd64.whl",
    "moderngl-5.12.0-cp311-cp311-macosx_10_9_x86_64.whl",
    "moderngl-5.12.0-cp313-cp313-macosx_10_13_x86_64.whl",
    "moderngl-5.13.0-cp311-cp311-macosx_11_0_arm64.whl",
    "moderngl-5.13.0-cp311-cp311-manylinux2014_x86_64.manylinux_2_17_x86_64.manylinux_2_28_x86_64.whl",
    "moderngl-5.13.0-cp311-cp311-win_amd64.whl",
    "moderngl-5.13.0-cp313-cp313-macosx_11_0_arm64.whl",
    "moderngl-5.13.0-cp313-cp313-manylinux2014_x86_64.manylinux_2_17_x86_64.manylinux_2_28_x86_64.whl",
    "moderngl-5.13.0-cp313-cp313-win_amd64.whl",
]
EXPECT = {"linux_x64": r"^manylinux.*_x86_64$", "windows_x64": r"^win_amd64$",
          "macos_arm64": r"^macosx_.*_(arm64|universal2)$", "macos_x64": r"^macosx_.*_(x86_64|universal2)$"}


def _build(tmp_path, builder):
    wheels = tmp_path / "wheels"
    if not wheels.exists():
        wheels.mkdir()
        for w in WHEELS:
            with zipfile.ZipFile(wheels / w, "w") as z:
                z.writestr(w.split("-")[0] + "/__init__.py", "")
    out = tmp_path / builder
    p = subprocess.run([sys.executable, BUILD, "--builder", builder, "--wheels-from", str(wheels), "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    return {os.path.basename(z).split("-")[-1][:-4]: z for z in sorted(glob.glob(str(out / "*.zip")))}


def test_each_platform_zip_carries_its_own_wheels(tmp_path):
    zips = _build(tmp_path, "self")
    assert sorted(zips) == sorted(EXPECT)
    for platform, path in zips.items():
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
            manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
        wheels = sorted(os.path.basename(n) for n in names if n.endswith(".whl"))
        assert len(wheels) == 4, (platform, wheels)         # 2 packages x Python 3.11 and 3.13
        assert all(re.match(EXPECT[platform], w.split("-")[-1][:-4]) for w in wheels), (platform, wheels)
        assert {w.split("-")[0] for w in wheels} == {"moderngl", "glcontext"}
        assert {w.split("-")[2] for w in wheels} == {"cp311", "cp313"}
        assert manifest["build"]["generated"]["platforms"] == [platform.replace("_", "-")]
        assert "website" not in manifest and manifest["license"] == ["SPDX:GPL-3.0-or-later"]
        assert "LICENSE" in names and "__init__.py" in names and "core/gl/renderer.py" in names
        assert not any(n.startswith(("tests/", "tools/", "sample_scenes/")) for n in names)


def _imports_lab(path, source):
    """Whether the module at ``path`` ("core/engine.py") imports the lab (``core.lab``) in any spelling."""
    for node in ast.walk(ast.parse(source, filename=path)):
        if isinstance(node, ast.Import):
            modules = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            package = path.split("/")[:-1]                       # the folder: a relative import's level 1
            base = package[:len(package) - (node.level - 1)] if node.level else []
            modules = [".".join(base + ([node.module] if node.module else []) + [a.name]) for a in node.names]
        else:
            continue
        if any("lab" in m.split(".") for m in modules):
            return True
    return False


def test_the_zip_holds_no_lab_code(tmp_path):
    """Benchmarks, reports, the CLI and jobs (core/lab/) stay out of the extension, and
    nothing that ships imports them."""
    for path in _build(tmp_path, "self").values():
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
            assert "core/engine.py" in names and "occ_addon/__init__.py" in names
            assert not [n for n in names if n.startswith("core/lab/") or n == "core/__main__.py"]
            importers = [n for n in names if n.endswith(".py") and _imports_lab(n, z.read(n).decode("utf-8"))]
            assert not importers, importers


def test_lab_imports_are_recognised():
    assert _imports_lab("core/__main__.py", "from .lab.cli import main")
    assert _imports_lab("core/engine.py", "from . import lab")
    assert _imports_lab("occ_addon/session.py", "from ..core.lab import motion")
    assert _imports_lab("occ_addon/session.py", "import core.lab.bench")
    assert not _imports_lab("core/engine.py", "from .motion import LivePolicy\nimport collections")
    assert not _imports_lab("occ_addon/live.py", "from ..core.motion import MotionTracker")


@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs bpy (Blender's extension CLI)")
def test_own_writer_equals_blenders_build_and_validates(tmp_path):
    ours, blenders = _build(tmp_path, "self"), _build(tmp_path, "bpy")
    assert sorted(ours) == sorted(blenders)
    for platform in ours:
        with zipfile.ZipFile(ours[platform]) as a, zipfile.ZipFile(blenders[platform]) as b:
            assert sorted(a.namelist()) == sorted(b.namelist()), platform
            assert a.read("blender_manifest.toml") == b.read("blender_manifest.toml"), platform
    cli = glob.glob(os.path.join(os.path.dirname(importlib.util.find_spec("bpy").origin), "*", "scripts",
                                 "addons_core", "bl_pkg", "cli", "blender_ext.py"))[0]
    for path in ours.values():
        p = subprocess.run([sys.executable, cli, "validate", path], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stdout + p.stderr


def test_license_is_the_gpl3_the_manifest_names():
    with open(os.path.join(ROOT, "LICENSE"), encoding="utf-8") as f:
        text = f.read()
    assert "GNU GENERAL PUBLIC LICENSE" in text and "Version 3, 29 June 2007" in text
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as f:
        assert tomllib.load(f)["license"] == ["SPDX:GPL-3.0-or-later"]


def test_a_blender_too_old_for_extensions_is_passed_over(tmp_path):
    """Debian's Blender 3.4 on PATH has no `--command extension`: the build goes on without it,
    and naming it explicitly is a one-line error."""
    fake = tmp_path / "bin" / "blender"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\necho 'Blender 3.4.1'\n")
    fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{fake.parent}{os.pathsep}{os.environ['PATH']}"}
    env.pop("BLENDER", None)
    p = subprocess.run([sys.executable, BUILD, "--no-wheels", "--builder", "auto", "--out", str(tmp_path / "out")],
                       cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "too old to build extensions" in p.stdout and len(glob.glob(str(tmp_path / "out" / "*.zip"))) == 1
    p = subprocess.run([sys.executable, BUILD, "--no-wheels", "--blender", str(fake), "--out", str(tmp_path / "o2")],
                       cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert p.returncode == 1 and "needs Blender 4.2 or later" in p.stderr
