"""Build the Blender extension zip(s) into dist/ with Blender's own extension CLI.

    python tools/build_extension.py              # with moderngl/glcontext wheels, split per platform
    python tools/build_extension.py --no-wheels  # one zip without wheels (tests: the venv has moderngl)

Without a Blender binary, the CLI is the script inside the bpy wheel
(bpy/<ver>/scripts/addons_core/bl_pkg/cli/blender_ext.py); each zip is then
checked with its ``validate`` command.  Wheels are downloaded by pip (never
committed) for Python 3.11 (Blender 4.2-5.0) and 3.13 (5.1+).
"""

import argparse
import glob
import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXTENSION_FILES = ("__init__.py", "blender_manifest.toml", "occ_addon", "core")
WHEEL_PACKAGES = ("moderngl", "glcontext")
PYTHONS = ("3.11", "3.13")
PLATFORMS = {   # Blender platform -> pip platform tags
    "linux-x64": ["manylinux_2_17_x86_64", "manylinux2014_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_11_0_arm64", "macosx_10_9_universal2", "macosx_11_0_universal2"],
}


def blender_cli():
    """Path of blender_ext.py inside the installed bpy wheel."""
    try:
        import bpy  # noqa: F401  (only to locate the package; nothing is run)
    except ImportError:
        sys.exit("building the extension needs bpy (pip install bpy==5.0.1) or a Blender binary")
    import importlib.util
    base = os.path.dirname(importlib.util.find_spec("bpy").origin)
    hits = glob.glob(os.path.join(base, "*", "scripts", "addons_core", "bl_pkg", "cli", "blender_ext.py"))
    if not hits:
        sys.exit(f"no blender_ext.py under {base}")
    return hits[0]


def copy_sources(dest):
    if os.path.exists(dest):
        shutil.rmtree(dest)
    os.makedirs(dest)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in EXTENSION_FILES:
        src = os.path.join(ROOT, name)
        if os.path.isdir(src):
            shutil.copytree(src, os.path.join(dest, name), ignore=ignore)
        else:
            shutil.copy2(src, dest)


def download_wheels(dest):
    os.makedirs(dest, exist_ok=True)
    for py in PYTHONS:
        for tags in PLATFORMS.values():
            cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:", "--no-deps",
                   "--python-version", py, "--implementation", "cp", "-d", dest]
            for t in tags:
                cmd += ["--platform", t]
            subprocess.run(cmd + list(WHEEL_PACKAGES), check=True)
    return sorted(os.listdir(dest))


def write_manifest(ext_dir, wheels):
    path = os.path.join(ext_dir, "blender_manifest.toml")
    with open(path, encoding="utf-8") as f:
        text = f.read()
    lines = ["platforms = [" + ", ".join(f'"{p}"' for p in PLATFORMS) + "]"]
    if wheels:
        lines.append("wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]")
    # top-level keys must come before the first [table]
    text = re.sub(r"^\[permissions\]", "\n".join(lines) + "\n\n[permissions]", text, count=1, flags=re.M)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--no-wheels", action="store_true", help="one zip without bundled wheels")
    p.add_argument("--out", default=os.path.join(ROOT, "dist"))
    args = p.parse_args()
    cli = blender_cli()
    ext = os.path.join(ROOT, "build", "ext")
    copy_sources(ext)
    wheels = [] if args.no_wheels else download_wheels(os.path.join(ext, "wheels"))
    write_manifest(ext, wheels)
    os.makedirs(args.out, exist_ok=True)
    for old in glob.glob(os.path.join(args.out, "*.zip")):
        os.remove(old)
    build = [sys.executable, cli, "build", "--source-dir", ext, "--output-dir", args.out]
    if wheels:
        build.append("--split-platforms")
    subprocess.run(build, check=True)
    zips = sorted(glob.glob(os.path.join(args.out, "*.zip")))
    for z in zips:
        subprocess.run([sys.executable, cli, "validate", z], check=True)
        print(f"built and validated {os.path.relpath(z, ROOT)} ({os.path.getsize(z) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
