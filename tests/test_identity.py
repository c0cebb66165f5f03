"""Stable identity: a glTF's objects get the same names and order in every run, Blender-style."""

import json
import os
import struct
import subprocess
import sys

import numpy as np
import pytest

from core.loading import blender_names, load_scene
from tests.cli_helpers import ROOT


def _glb(header, binary):
    """A GLB file from a glTF header and its binary buffer (chunks padded to 4 bytes)."""
    js = json.dumps(header).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def _split_glb(data):
    n = struct.unpack_from("<I", data, 12)[0]
    header = json.loads(data[20:20 + n])
    m = struct.unpack_from("<I", data, 20 + n)[0]
    return header, data[28 + n:28 + n + m]


@pytest.fixture(scope="module")
def messy_gltf(tmp_path_factory):
    """Five boxes in a row exported by trimesh, then renamed the way CAD exports come:
    two nodes called "part", one "part.001" given explicitly, one without a name, and one
    unnamed node whose mesh has two primitives (trimesh names those randomly)."""
    import trimesh
    s = trimesh.Scene()
    for k in range(5):
        s.add_geometry(trimesh.creation.box((1, 1, 1)), node_name=f"n{k}", geom_name=f"g{k}",
                       transform=trimesh.transformations.translation_matrix((3 * k, 0, 0)))
    header, binary = _split_glb(s.export(file_type="glb"))
    by_name = {n["name"]: n for n in header["nodes"]}
    by_name["n0"]["name"] = "part"
    by_name["n1"]["name"] = "part"
    by_name["n2"]["name"] = "part.001"
    del by_name["n3"]["name"]
    mesh3 = header["meshes"][by_name["n3"]["mesh"]]
    mesh3["name"] = "bolt"
    del by_name["n4"]["name"]
    mesh4 = header["meshes"][by_name["n4"]["mesh"]]
    mesh4.pop("name", None)
    # n4's mesh gets a second primitive (n0's box, in n4's frame)
    mesh4["primitives"].append(dict(header["meshes"][by_name["n0"]["mesh"]]["primitives"][0]))
    path = tmp_path_factory.mktemp("identity") / "messy.glb"
    path.write_bytes(_glb(header, binary))
    return path, header


def test_blender_names():
    assert blender_names(["a", "a", "a.001", "b", "a"]) == ["a", "a.001", "a.002", "b", "a.003"]
    assert blender_names(["x.001", "x.001", "x"]) == ["x.001", "x.002", "x"]


def test_repeated_and_missing_names_are_deterministic(messy_gltf):
    path, header = messy_gltf
    a, b = load_scene(path), load_scene(path)
    assert a.names == b.names
    # file order: node index order of the exported file
    bases = [n.get("name") or header["meshes"][n["mesh"]].get("name") or "object" for n in header["nodes"]]
    assert a.names == blender_names(bases)
    assert sorted(a.names) == sorted(["part", "part.001", "part.002", "bolt", "object"])
    # the two-primitive node is one object with both primitives' triangles
    assert sorted(a.triangle_counts.tolist()) == [12, 12, 12, 12, 24]
    assert np.allclose(a.matrices, b.matrices)


def test_names_are_stable_across_processes(messy_gltf):
    path, _ = messy_gltf
    code = "import sys; from core.loading import load_scene; print('|'.join(load_scene(sys.argv[1]).names))"
    runs = {subprocess.run([sys.executable, "-c", code, str(path)], cwd=ROOT, capture_output=True, text=True,
                           check=True, env={**os.environ, "PYTHONHASHSEED": str(seed)}).stdout
            for seed in (1, 2)}
    assert len(runs) == 1


def test_cull_and_truth_json_give_every_objects_state(messy_gltf, tmp_path):
    path, _ = messy_gltf
    cam = tmp_path / "cam.json"
    # looking down the row of boxes: the first hides the rest; one camera looks away
    cam.write_text(json.dumps({"frames": [{"eye": [-10, 0, 0], "target": [0, 0, 0]},
                                          {"eye": [-10, 0, 0], "target": [-20, 0, 0]}]}))
    out = {}
    for cmd in ("cull", "truth"):
        p = subprocess.run([sys.executable, "-m", "core", cmd, str(path), "--camera", str(cam),
                            "--resolution", "96x64", "--json"], cwd=ROOT, capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        out[cmd] = json.loads(p.stdout)["frames"]
    names = load_scene(path).names
    for cmd, frames in out.items():
        for f in frames:
            assert [o["index"] for o in f["objects"]] == list(range(len(names)))
            assert [o["name"] for o in f["objects"]] == names
            assert f["visible"] == [o["name"] for o in f["objects"] if o["state"] == "visible"]
        first = {o["name"]: o["state"] for o in frames[0]["objects"]}
        assert first[names[0]] == "visible" and list(first.values()).count("occluded") == 4, (cmd, first)
        assert {o["state"] for o in frames[1]["objects"]} == {"view_culled"}, cmd
    # what truth sees, cull keeps (conservative), object by object
    for t, c in zip(out["truth"], out["cull"], strict=True):
        assert set(t["visible"]) <= set(c["visible"])


def test_gltf_with_external_buffers_loads_like_glb(tmp_path):
    import trimesh
    s = trimesh.Scene()
    s.add_geometry(trimesh.creation.box((1, 1, 1)), node_name="a", geom_name="g")
    s.add_geometry(trimesh.creation.icosphere(), node_name="b", geom_name="h",
                   transform=trimesh.transformations.translation_matrix((3, 0, 0)))
    for name, data in s.export(file_type="gltf").items():
        (tmp_path / name).write_bytes(data)
    s.export(tmp_path / "same.glb")
    a, b = load_scene(tmp_path / "model.gltf"), load_scene(tmp_path / "same.glb")
    assert a.names == b.names == ["a", "b"]
    assert np.array_equal(a.triangle_counts, b.triangle_counts)
    assert np.allclose(a.bounds, b.bounds) and np.allclose(a.bounds[1], [[2, -1, -1], [4, 1, 1]])


def test_node_transforms_match_trimesh(tmp_path):
    """Translation, rotation (xyzw quaternion) and scale, under a parent with a matrix: the
    world matrices equal those trimesh's own loader computes."""
    import trimesh

    from core.loading import scene_from_trimesh
    s = trimesh.Scene()
    s.add_geometry(trimesh.creation.box((1, 2, 3)), node_name="child", geom_name="g")
    header, binary = _split_glb(s.export(file_type="glb"))
    child = next(i for i, n in enumerate(header["nodes"]) if n.get("name") == "child")
    header["nodes"][child].pop("matrix", None)
    header["nodes"][child].update(translation=[1.0, 2.0, 3.0], rotation=[0.1, 0.7, 0.2, 0.68],
                                  scale=[2.0, 0.5, 1.5])
    parent = {"name": "parent", "children": [child],
              "matrix": trimesh.transformations.rotation_matrix(0.7, (1, 1, 0), (4, 0, 0)).T.ravel().tolist()}
    header["nodes"].append(parent)
    header["scenes"][header.get("scene", 0)]["nodes"] = [len(header["nodes"]) - 1]
    path = tmp_path / "trs.glb"
    path.write_bytes(_glb(header, binary))
    ours = load_scene(path)
    theirs = scene_from_trimesh(trimesh.load(path, force="scene"))
    assert ours.names == theirs.names == ["child"]
    assert np.allclose(ours.matrices, theirs.matrices, atol=1e-12)
    assert np.allclose(ours.bounds, theirs.bounds)
