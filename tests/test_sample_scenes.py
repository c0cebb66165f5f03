"""Sample scenes: deterministic, structured as the engine expects, valid camera paths."""

import numpy as np
import pytest

import sample_scenes
from core import load_scene
from core.camera import cameras_from_json


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("scenes")


def count(scene):
    return (len(scene.graph.nodes_geometry),
            sum(len(scene.geometry[scene.graph[n][1]].faces) for n in scene.graph.nodes_geometry))


@pytest.mark.parametrize("name", [n for n in sample_scenes.NAMES if n != "isosurface"])
def test_small_scenes_are_deterministic_and_load(name, cache):
    a, b = sample_scenes.build_scene(name, small=True), sample_scenes.build_scene(name, small=True)
    assert count(a) == count(b) and np.allclose(a.bounds, b.bounds)
    scene = load_scene(sample_scenes.scene_path(name, cache, small=True))
    objects, tris = count(a)
    assert len(scene) == objects and scene.triangle_counts.sum() == tris
    assert len(set(scene.names)) == len(scene.names)
    assert len(scene.meshes) < len(scene)            # repeated parts share meshes


@pytest.mark.parametrize("name", sample_scenes.NAMES)
def test_camera_paths_are_valid(name):
    for path in sample_scenes.camera_paths(name, small=True).values():
        cams = cameras_from_json(path)            # raises on NaN, eye == target, bad near/far
        assert 60 <= len(cams) <= 120
        for f in path["frames"]:
            assert f["near"] > 0 and f["far"] / f["near"] <= 1e5


def test_city_tree_groups_buildings_and_rooms(cache):
    scene = load_scene(sample_scenes.scene_path("city", cache, small=True))
    vase = [i for i, n in enumerate(scene.names) if n.endswith("/vase")]
    assert vase and all(scene.tree_parent[np.flatnonzero(scene.tree_object == i)[0]] >= 0 for i in vase)


def test_isosurface_walk_stays_inside_the_cave():
    from sample_scenes import isosurface
    frames = isosurface.paths()["walk"]["frames"]
    eyes = np.array([f["eye"] for f in frames]) / 40.0
    assert np.all(isosurface.field(eyes) < -0.05)


def test_unknown_name_is_a_clear_error():
    with pytest.raises(ValueError, match="choose one of city"):
        sample_scenes.scene_path("moon")


@pytest.mark.slow
def test_full_city_size(cache):
    objects, tris = count(sample_scenes.build_scene("city"))
    assert objects >= 1500 and tris >= 4_000_000
