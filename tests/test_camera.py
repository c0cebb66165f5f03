import math

import numpy as np
import pytest

from core import Camera, OccError
from core.camera import cameras_from_json, look_at, orthographic, perspective


def test_look_at_maps_eye_to_origin_and_target_down_minus_z():
    v = look_at([1, 2, 3], [1, 12, 3], [0, 0, 1])
    assert np.allclose(v @ [1, 2, 3, 1], [0, 0, 0, 1])
    assert np.allclose(v @ [1, 12, 3, 1], [0, 0, -10, 1])
    assert np.allclose(v[:3, :3] @ v[:3, :3].T, np.eye(3))


def test_perspective_maps_near_and_far_to_ndc_bounds():
    p = perspective(90.0, 2.0, 0.5, 100.0)
    for z, ndc in ((-0.5, -1.0), (-100.0, 1.0)):
        c = p @ [0, 0, z, 1]
        assert math.isclose(c[2] / c[3], ndc, abs_tol=1e-12)
    c = p @ [2.0, 1.0, -1.0, 1]          # 45 deg up and, at aspect 2, the right edge
    assert np.allclose(c[:2] / c[3], [1.0, 1.0])


def test_orthographic_extent():
    p = orthographic(10.0, 1.5, 0.0, 50.0)
    assert np.allclose((p @ [7.5, 5.0, -50.0, 1])[:3], [1, 1, 1])
    assert np.allclose((p @ [-7.5, -5.0, 0.0, 1])[:3], [-1, -1, -1])


def test_relative_view_projection_equals_world_form():
    cam = Camera.look_at([1e6 + 3, -2e6, 5e5], [1e6, -2e6 + 10, 5e5 + 1], near=0.1, far=100)
    p = np.array([1e6 + 1, -2e6 + 7, 5e5 - 2, 1.0])
    world = cam.view_projection() @ p
    rel = cam.relative_view_projection() @ np.append(p[:3] - cam.eye, 1.0)
    assert np.allclose(world, rel, rtol=1e-9, atol=1e-6)
    assert np.allclose(cam.eye, [1e6 + 3, -2e6, 5e5], rtol=0, atol=1e-6)


@pytest.mark.parametrize("bad, message", [
    ({"eye": [0, 0, float("nan")], "target": [1, 0, 0]}, "finite"),
    ({"eye": [0, 0, 0], "target": [1, 0, float("inf")]}, "finite"),
    ({"eye": [0, 0, 0], "target": [0, 0, 0]}, "coincide"),
    ({"eye": [0, 0, 0], "target": [0, 0, 5]}, "parallel"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "near": 0.0}, "near > 0"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "near": 10, "far": 1}, "far must be > near"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "fov_y_deg": 180}, "fov_y_deg"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "aspect": 0}, "aspect"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "ortho_height": -1}, "ortho_height"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "zoom": 2}, "unknown camera keys"),
    ({"eye": [0, 0], "target": [1, 0, 0]}, "list of 3 numbers"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "up": [0, 0, 0]}, "up .* has zero length"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "fov_y_deg": True}, "fov_y_deg must be a number, got true"),
    ({"eye": [0, 0, 0], "target": [1, 0, 0], "near": "0.1"}, "near must be a number, got a string"),
    ({"eye": [0, "1", 0], "target": [1, 0, 0]}, "eye must be a list of 3 numbers"),
    ({"target": [1, 0, 0]}, "needs 'eye'"),
    ({"eye": "here", "target": [1, 0, 0]}, "camera"),
])
def test_bad_cameras_raise_clear_errors(bad, message):
    with pytest.raises(OccError, match=message):
        Camera.from_dict(bad)


def test_frames_json():
    cams = cameras_from_json({"frames": [{"eye": [0, 0, 0], "target": [1, 0, 0]},
                                         {"eye": [0, 0, 0], "target": [0, 1, 0],
                                          "ortho_height": 3.0}]})
    assert len(cams) == 2 and cams[1].is_orthographic and not cams[0].is_orthographic
    with pytest.raises(OccError, match="non-empty"):
        cameras_from_json({"frames": []})


def test_nan_matrix_camera_rejected():
    v = np.eye(4)
    v[0, 3] = np.nan
    with pytest.raises(OccError, match="finite"):
        Camera.from_matrices(v, np.eye(4))
