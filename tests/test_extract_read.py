"""The add-on's mesh read in real bpy (5.0.1 from PyPI), in a subprocess: float32 /
int32 arrays as Blender holds them, the position attribute read equal to
``vertices.co``, and the direct read of a plain mesh equal to its ``to_mesh`` copy."""

import importlib.util
import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PYTHON = os.environ.get("OCC_BPY_PYTHON", sys.executable)

pytestmark = [
    pytest.mark.blender,
    pytest.mark.skipif(PYTHON == sys.executable and importlib.util.find_spec("bpy") is None,
                       reason="bpy is not installed (make test installs bpy==5.0.1)"),
]

SCRIPT = r"""
import importlib, json, sys
import bpy, numpy as np
sys.path.insert(0, PARENT)
meshes = importlib.import_module(PKG + ".occ_addon.meshes")
out = {}
bpy.ops.mesh.primitive_uv_sphere_add(segments=17, ring_count=9)
plain = bpy.context.object
plain.shape_key_add(name="Basis")
k = plain.shape_key_add(name="k"); k.value = 0.5
for p in k.data: p.co.x += 1.0                      # evaluated != original: the read must see it
bpy.ops.mesh.primitive_cube_add()
sub = bpy.context.object
sub.modifiers.new("s", "SUBSURF").levels = 2
dg = bpy.context.evaluated_depsgraph_get()
for name, ob in (("plain", plain), ("sub", sub)):
    oe = ob.evaluated_get(dg)
    v, f = meshes.mesh_arrays(oe)
    m = oe.to_mesh()
    co = np.empty(len(m.vertices) * 3, np.float32); m.vertices.foreach_get("co", co)
    m.calc_loop_triangles()
    tri = np.empty(len(m.loop_triangles) * 3, np.int32); m.loop_triangles.foreach_get("vertices", tri)
    oe.to_mesh_clear()
    out[name] = {"dtypes": [str(v.dtype), str(f.dtype)], "shape": [list(v.shape), list(f.shape)],
                 "co": bool(np.array_equal(v.ravel(), co)), "tri": bool(np.array_equal(f.ravel(), tri))}
    if name == "plain":
        dv, df = meshes.mesh_arrays(oe, True)
        out["direct"] = bool(np.array_equal(dv, v) and np.array_equal(df, f))
        out["shape_key_seen"] = bool(v[:, 0].max() > 1.2)
print("RESULT" + json.dumps(out))
"""


def test_mesh_read_in_bpy():
    parent, pkg = os.path.split(ROOT)
    code = f"PARENT = {parent!r}\nPKG = {pkg!r}\n" + SCRIPT
    run = subprocess.run([PYTHON, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)
    lines = [ln for ln in run.stdout.splitlines() if ln.startswith("RESULT")]
    assert lines, run.stdout[-2000:] + run.stderr[-2000:]
    out = json.loads(lines[-1][6:])
    for name in ("plain", "sub"):
        r = out[name]
        assert r["dtypes"] == ["float32", "int32"] and r["shape"][0][1] == 3 and r["shape"][1][1] == 3, r
        assert r["co"] and r["tri"], (name, r)
    assert out["sub"]["shape"][0][0] == 98                 # the modifier's result, not the cage
    assert out["direct"] and out["shape_key_seen"], out
