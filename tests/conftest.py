import json
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


@pytest.fixture(scope="session")
def gl_session():
    """One EGL context for the whole run (contexts are slow to make on llvmpipe)."""
    from core.gl import create_context

    ctx = create_context()
    yield ctx
    ctx.release()


@pytest.fixture
def ctx(gl_session):
    """The shared context, bracketed by a GL-error check as moderngl's own tests do."""
    assert gl_session.error == "GL_NO_ERROR"
    yield gl_session
    assert gl_session.error == "GL_NO_ERROR"


@pytest.fixture(scope="module")
def wall_scene(tmp_path_factory):
    """A glTF of a wall with a ball behind it, one beside it and one far behind the camera,
    and a two-frame camera file (from either side of the wall): ``(scene, cameras, folder)``."""
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
