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


def _start(script, work, zip_path, *args):
    """``script ZIP WORK *args`` started in Blender, in ``work`` with its own user folder."""
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(work / "user")}
    return subprocess.Popen([PYTHON, script, str(zip_path), str(work), *args], cwd=str(work), env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _results(script, p, out, err):
    line = next((ln for ln in out.splitlines() if ln.startswith("OCC_RESULTS ")), None)
    assert line is not None, (f"{os.path.basename(script)} printed no results (rc {p.returncode}):\n"
                              f"{out[-3000:]}\n{err[-3000:]}")
    return json.loads(line[len("OCC_RESULTS "):])


def run_script(script, work, *args, timeout=600):
    """Run ``script ZIP WORK *args`` in Blender; returns (the JSON of its ``OCC_RESULTS``
    line, the completed process)."""
    p = _start(script, work, build_zip(work), *args)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        raise
    return _results(script, p, out, err), subprocess.CompletedProcess(p.args, p.returncode, out, err)


# processes the cases share (``cases.py shard:K/N``): one per core, two at most (each
# Blender also draws on llvmpipe's threads); OCC_CASE_SHARDS overrides
SHARDS = int(os.environ.get("OCC_CASE_SHARDS", min(2, os.cpu_count() or 1)))


def run_sharded(script, work, root, timeout=1200):
    """Every case of ``script`` (``cases.py``), in :data:`SHARDS` Blender processes at once,
    each in its own folder; returns (every shard's results merged, a completed process
    whose output is every shard's, in order)."""
    zip_path = build_zip(work)
    procs = []
    for k in range(SHARDS):
        folder = work / f"shard{k}"
        folder.mkdir()
        procs.append(_start(script, folder, zip_path, root, f"shard:{k}/{SHARDS}"))
    results, outs, errs = {}, [], []
    try:
        for p in procs:
            out, err = p.communicate(timeout=timeout)
            results.update(_results(script, p, out, err))
            outs.append(out)
            errs.append(err)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    code = next((p.returncode for p in procs if p.returncode), 0)
    # each case's time (cases.py prints them), slowest first, for whoever trims the suite
    times = [ln.split()[1:] for e in errs for ln in e.splitlines() if ln.startswith("OCC_CASE_TIME ")]
    (work / "case_times.txt").write_text("".join(f"{t:>7} {name}\n" for name, t in
                                                 sorted(times, key=lambda x: -float(x[1]))))
    return results, subprocess.CompletedProcess([PYTHON, script], code, "".join(outs), "".join(errs))


def assert_check(results, name):
    """One check a script recorded: reached, and passed (its detail says why not)."""
    assert name in results, f"the script never reached '{name}'"
    ok, detail = results[name]
    assert ok, detail
