"""The command line as a user runs it: subprocesses, JSON shapes, clear errors."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(*args):
    return subprocess.run([sys.executable, "-m", "core", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)


@pytest.fixture(scope="module")
def wall_scene(tmp_path_factory):
    import trimesh
    d = tmp_path_factory.mktemp("cli")
    s = trimesh.Scene()
    s.add_geometry(trimesh.creation.box((1, 10, 10)), node_name="wall", geom_name="wall")
    ball = trimesh.creation.icosphere()
    s.add_geometry(ball, node_name="behind", geom_name="ball",
                   transform=trimesh.transformations.translation_matrix((5, 0, 0)))
    s.add_geometry(ball, node_name="beside", geom_name="ball",
                   transform=trimesh.transformations.translation_matrix((-5, 8, 0)))
    s.add_geometry(ball, node_name="back", geom_name="ball",
                   transform=trimesh.transformations.translation_matrix((-80, 0, 0)))
    path = d / "wall.glb"
    s.export(path)
    cam = {"eye": [-20, 0, 0], "target": [0, 0, 0], "up": [0, 0, 1], "fov_y_deg": 60.0,
           "aspect": 1.5, "near": 0.1, "far": 1000.0, "ortho_height": None}
    cam_path = d / "cam.json"
    cam_path.write_text(json.dumps({"frames": [cam, {**cam, "eye": [20, 0, 0]}]}))
    return path, cam_path, d


def test_cull_json_contract(wall_scene):
    path, cam, _ = wall_scene
    for strategy in ("vfc", "stopwait", "om", "om_multi", "oracle"):
        p = run("cull", str(path), "--camera", str(cam), "--strategy", strategy, "--json")
        assert p.returncode == 0, p.stderr
        frames = json.loads(p.stdout)["frames"]
        assert len(frames) == 2
        assert "queries" in frames[0]["stats"]
        assert {"wall", "beside"} <= set(frames[0]["visible"])
        assert "back" not in frames[0]["visible"]
        if strategy != "vfc":
            assert "behind" not in frames[0]["visible"]
            assert "behind" in frames[1]["visible"]


def test_truth_json_and_cull_contains_truth(wall_scene):
    path, cam, _ = wall_scene
    t = run("truth", str(path), "--camera", str(cam), "--resolution", "96x64", "--json")
    c = run("cull", str(path), "--camera", str(cam), "--resolution", "96x64", "--json")
    assert t.returncode == 0 and c.returncode == 0, t.stderr + c.stderr
    for tf, cf in zip(json.loads(t.stdout)["frames"], json.loads(c.stdout)["frames"], strict=True):
        assert set(tf["visible"]) <= set(cf["visible"])
    assert sorted(json.loads(t.stdout)["frames"][0]["visible"]) == ["beside", "wall"]


def test_text_output(wall_scene):
    path, cam, _ = wall_scene
    p = run("cull", str(path), "--camera", str(cam))
    assert p.returncode == 0 and p.stdout.startswith("frame 0: 2 of 4 visible")


@pytest.mark.parametrize("case, message", [
    ("missing", "scene file not found"),
    ("garbage", "cannot read scene file"),
    ("nan_camera", "finite"),
    ("zero_near", "near > 0"),
    ("bad_resolution", "resolution must"),
    ("zero_resolution", "resolution must be between"),
    ("camera_missing", "cannot read camera file"),
    ("camera_not_json", "not valid JSON"),
])
def test_user_errors_are_one_clear_line(wall_scene, case, message):
    path, cam, d = wall_scene
    good_cam = json.loads(cam.read_text())["frames"][0]
    args = [str(path), "--camera", str(cam)]
    if case == "missing":
        args[0] = str(d / "nope.glb")
    elif case == "garbage":
        g = d / "garbage.glb"
        g.write_bytes(b"glTF\x02\x00\x00\x00" + np.random.default_rng(0).bytes(200))
        args[0] = str(g)
    elif case in ("nan_camera", "zero_near"):
        bad = dict(good_cam, eye=[float("nan"), 0, 0]) if case == "nan_camera" else dict(good_cam, near=0)
        f = d / f"{case}.json"
        f.write_text(json.dumps(bad))
        args[2] = str(f)
    elif case == "bad_resolution":
        args += ["--resolution", "big"]
    elif case == "zero_resolution":
        args += ["--resolution", "0x10"]
    elif case == "camera_missing":
        args[2] = str(d / "none.json")
    elif case == "camera_not_json":
        f = d / "broken.json"
        f.write_text("{eye: ")
        args[2] = str(f)
    p = run("cull", *args)
    assert p.returncode == 2
    assert message in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def test_empty_scene_file_gives_empty_answer(wall_scene, tmp_path):
    _, cam, _ = wall_scene
    obj = tmp_path / "empty.obj"
    obj.write_text("# nothing here\n")
    p = run("cull", str(obj), "--camera", str(cam), "--json")
    assert p.returncode == 0, p.stderr
    assert [f["visible"] for f in json.loads(p.stdout)["frames"]] == [[], []]


def test_missing_egl_names_the_packages(wall_scene):
    """Without a loadable libEGL the user is told which packages to install."""
    path, cam, _ = wall_scene
    p = subprocess.run([sys.executable, "-m", "core", "cull", str(path), "--camera", str(cam)],
                       cwd=ROOT, capture_output=True, text=True, timeout=120,
                       env={**os.environ, "OCC_LIBEGL": "libEGL-missing.so.1"})
    assert p.returncode == 2, p.stderr
    assert "libegl1 libegl-mesa0 libgl1-mesa-dri" in p.stderr and "Traceback" not in p.stderr
