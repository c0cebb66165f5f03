"""Build the Blender extension zip(s) into dist/, one per platform, with the wheels it needs.

    python3 tools/build_extension.py                    # what `make extension` runs
    python3 tools/build_extension.py --blender /path/to/blender
    python3 tools/build_extension.py --no-wheels        # one zip without wheels (tests: moderngl is there)

Needs only a Python 3.11+ with pip (for ``pip download`` of the moderngl and glcontext
wheels for Python 3.11, Blender 4.2-5.0, and 3.13, Blender 5.1+).  The zips are built
by the first of:

1. a Blender binary (``--blender``, ``$BLENDER`` or ``blender`` on PATH): Blender's own
   ``blender --command extension build --split-platforms`` and ``extension validate``;
2. the ``bpy`` module of this Python (the test venv): the same CLI script inside bpy;
3. neither: this script writes the zips itself the way Blender's build does (the same
   files, each platform's wheels, the generated manifest block); the test suite checks
   that its zips equal Blender's and pass Blender's validator (tests/test_extension.py).
"""

import argparse
import fnmatch
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXTENSION_FILES = ("__init__.py", "blender_manifest.toml", "LICENSE", "occ_addon", "core")
WHEEL_PACKAGES = ("moderngl", "glcontext")
PYTHONS = ("3.11", "3.13")
PLATFORMS = {   # Blender platform -> pip platform tags to ask for (pip picks the best it finds)
    "linux-x64": ["manylinux_2_17_x86_64", "manylinux2014_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_11_0_arm64", "macosx_10_9_universal2", "macosx_11_0_universal2"],
    "macos-x64": ["macosx_10_9_x86_64", "macosx_10_13_x86_64", "macosx_11_0_x86_64",
                  "macosx_10_9_universal2"],
}
# A wheel's platform tag -> the Blender platforms it serves (Blender's own rule, for our tags).
WHEEL_TAGS = ((r"^(manylinux|musllinux|linux)[0-9_]*.*x86_64$", ("linux-x64",)),
              (r"^win_amd64$", ("windows-x64",)),
              (r"^macosx_.*_arm64$", ("macos-arm64",)),
              (r"^macosx_.*_x86_64$", ("macos-x64",)),
              (r"^macosx_.*_universal2$", ("macos-x64", "macos-arm64")),
              (r"^any$", tuple(PLATFORMS)))


def wheel_platforms(wheel):
    """Blender platforms a wheel file serves, from its platform tag (the last name field)."""
    tag = os.path.splitext(os.path.basename(wheel))[0].split("-")[-1]
    for pattern, platforms in WHEEL_TAGS:
        if re.match(pattern, tag.split(".")[0]) or re.match(pattern, tag):
            return platforms
    return ()


MIN_BLENDER = (4, 2)         # the first Blender with `--command extension`


def blender_version(path):
    """``(major, minor)`` of a Blender binary, from ``blender --version``, or None."""
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=120).stdout
    except (OSError, subprocess.TimeoutExpired):
        return None
    m = re.search(r"^Blender (\d+)\.(\d+)", out, flags=re.M)
    return (int(m.group(1)), int(m.group(2))) if m else None


def find_blender(arg):
    """The Blender to build with: the one asked for (it must be 4.2+), else a 4.2+ on PATH, else None."""
    asked = arg or os.environ.get("BLENDER")
    path = asked or shutil.which("blender")
    if not path:
        return None
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        sys.exit(f"error: no Blender binary at {path}")
    version = blender_version(path)
    if version is None or version < MIN_BLENDER:
        found = "an unknown version" if version is None else "Blender {}.{}".format(*version)
        if asked:
            sys.exit(f"error: {path} is {found}; building extensions needs Blender 4.2 or later")
        print(f"note: {path} is {found}, too old to build extensions (4.2+); building without it")
        return None
    return path


def bpy_cli():
    """Path of blender_ext.py inside this Python's bpy module, or None."""
    import importlib.util
    spec = importlib.util.find_spec("bpy")
    if spec is None:
        return None
    hits = glob.glob(os.path.join(os.path.dirname(spec.origin), "*", "scripts", "addons_core", "bl_pkg",
                                  "cli", "blender_ext.py"))
    return hits[0] if hits else None


def manifest_excludes():
    """The manifest's ``paths_exclude_pattern``: ``(anchored, anywhere)``, the entries that
    name a path from the root (``"/core/lab/"``) as lists of name patterns (``["core",
    "lab"]``), and the name patterns that match at any depth (``"ruff.toml"``)."""
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as f:
        patterns = tomllib.load(f)["build"]["paths_exclude_pattern"]
    return ([p.strip("/").split("/") for p in patterns if p.startswith("/")],
            [p.rstrip("/") for p in patterns if not p.startswith("/") and "/" not in p.rstrip("/")])


def excluded(rel, anchored):
    """Whether the source path ``rel`` ("core/lab/cli.py") is, or lies under, an anchored pattern."""
    parts = rel.replace(os.sep, "/").split("/")
    return any(len(parts) >= len(pat) and all(fnmatch.fnmatch(a, b) for a, b in zip(parts, pat, strict=False))
               for pat in anchored)


def copy_sources(dest):
    """The extension's files into ``dest``, less what the manifest excludes (the lab, the CLI
    entry point): both builders then see the same source folder."""
    if os.path.exists(dest):
        shutil.rmtree(dest)
    os.makedirs(dest)
    anchored, anywhere = manifest_excludes()
    default = shutil.ignore_patterns("__pycache__", "*.pyc", ".*", *anywhere)

    def ignore(folder, names):
        rel = os.path.relpath(folder, ROOT)
        return set(default(folder, names)) | {n for n in names if excluded(os.path.join(rel, n), anchored)}

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
            if subprocess.run(cmd + list(WHEEL_PACKAGES)).returncode:
                sys.exit(f"error: pip could not download {' '.join(WHEEL_PACKAGES)} for Python {py} on "
                         f"{', '.join(tags)}; check the network, or pass --wheels-from DIR")
    return sorted(os.listdir(dest))


def check_wheels(wheels):
    """Every platform gets moderngl and glcontext for every Python, or the build stops."""
    missing = []
    for platform in PLATFORMS:
        for py in PYTHONS:
            cp = "cp" + py.replace(".", "")
            for pkg in WHEEL_PACKAGES:
                if not any(w.startswith(pkg + "-") and f"-{cp}-" in w and platform in wheel_platforms(w)
                           for w in wheels):
                    missing.append(f"{pkg} for {cp} on {platform}")
    if missing:
        sys.exit("error: no wheel of " + "; ".join(missing))


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


def write_zips(ext_dir, out_dir, split):
    """What Blender's ``extension build [--split-platforms]`` writes for this source folder."""
    with open(os.path.join(ext_dir, "blender_manifest.toml"), "rb") as f:
        manifest_bytes = f.read()
    manifest = tomllib.loads(manifest_bytes.decode("utf-8"))
    files = sorted(os.path.relpath(os.path.join(d, n), ext_dir).replace(os.sep, "/")
                   for d, _, names in os.walk(ext_dir) for n in names)
    wheels = manifest.get("wheels", [])
    zips = []
    for platform in (manifest.get("platforms", []) if split else [None]):
        keep = [w for w in wheels if platform is None or platform in wheel_platforms(w)]
        name = f"{manifest['id']}-{manifest['version']}" + (f"-{platform.replace('-', '_')}" if platform else "")
        path = os.path.join(out_dir, name + ".zip")
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
            for rel in files:
                if rel.startswith("wheels/") and "./" + rel not in keep:
                    continue
                stored = zipfile.ZIP_STORED if rel.endswith(".whl") else None
                if rel == "blender_manifest.toml" and platform:
                    block = ("\n\n# BEGIN GENERATED CONTENT.\n# This must not be included in source manifests.\n"
                             f'[build.generated]\nplatforms = ["{platform}"]\nwheels = ['
                             + ", ".join(f'"{w}"' for w in keep) + "]\n# END GENERATED CONTENT.\n")
                    z.writestr(rel, manifest_bytes + block.encode("utf-8"), compress_type=stored)
                else:
                    z.write(os.path.join(ext_dir, rel), rel, compress_type=stored)
        zips.append(path)
    return zips


def plain_zip(out):
    """Build the one zip without wheels into ``out`` (as a tool or test installs it), in a
    subprocess; its path."""
    subprocess.run([sys.executable, os.path.abspath(__file__), "--no-wheels", "--out", out],
                   check=True, capture_output=True, timeout=300)
    zips = sorted(f for f in os.listdir(out) if f.endswith(".zip"))
    if len(zips) != 1:
        raise SystemExit(f"expected one extension zip in {out}, got {zips}")
    return os.path.join(out, zips[0])


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--no-wheels", action="store_true", help="one zip without bundled wheels")
    p.add_argument("--wheels-from", help="use the wheels in this folder instead of downloading them")
    p.add_argument("--blender", help="Blender binary to build and validate with (default $BLENDER or PATH)")
    p.add_argument("--builder", choices=("auto", "blender", "bpy", "self"), default="auto",
                   help="who writes the zips (auto: the first of Blender, bpy, this script)")
    p.add_argument("--out", default=os.path.join(ROOT, "dist"))
    args = p.parse_args()
    blender = find_blender(args.blender) if args.builder in ("auto", "blender") else None
    cli = bpy_cli() if args.builder in ("auto", "bpy") and not blender else None
    if args.builder == "blender" and not blender:
        sys.exit("error: no Blender found; pass --blender /path/to/blender")
    if args.builder == "bpy" and not cli:
        sys.exit("error: this Python has no bpy module")
    # a staging folder of its own: builds running at once (tests, a user) never share one
    stage = tempfile.mkdtemp(prefix="occ-extension-")
    try:
        return build(args, blender, cli, os.path.join(stage, "ext"))
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def build(args, blender, cli, ext):
    copy_sources(ext)
    wheel_dir = os.path.join(ext, "wheels")
    if args.no_wheels:
        wheels = []
    elif args.wheels_from:
        shutil.copytree(args.wheels_from, wheel_dir)
        wheels = sorted(w for w in os.listdir(wheel_dir) if w.endswith(".whl"))
    else:
        wheels = download_wheels(wheel_dir)
    if wheels:
        check_wheels(wheels)
    write_manifest(ext, wheels)
    os.makedirs(args.out, exist_ok=True)
    for old in glob.glob(os.path.join(args.out, "*.zip")):
        os.remove(old)
    split = ["--split-platforms"] if wheels else []
    if blender:
        run = [blender, "--factory-startup", "--command", "extension"]
        subprocess.run(run + ["build", "--source-dir", ext, "--output-dir", args.out] + split, check=True)
        validate = [run + ["validate"]]
    elif cli:
        subprocess.run([sys.executable, cli, "build", "--source-dir", ext, "--output-dir", args.out] + split,
                       check=True)
        validate = [[sys.executable, cli, "validate"]]
    else:
        write_zips(ext, args.out, bool(split))
        validate = []
    for z in sorted(glob.glob(os.path.join(args.out, "*.zip"))):
        for v in validate:
            subprocess.run(v + [z], check=True)
        with zipfile.ZipFile(z) as f:
            inside = sorted(os.path.basename(n) for n in f.namelist() if n.endswith(".whl"))
        how = "built and validated" if validate else "built"
        print(f"{how} {os.path.relpath(z)} ({os.path.getsize(z) / 1e6:.1f} MB): "
              f"{', '.join(inside) or 'no wheels'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
