"""What a command works on: sample names, their fitted camera paths, frame spreading."""

import numpy as np
import pytest

import sample_scenes
from core import Culler, OccError
from core.camera import cameras_from_json
from core.lab.jobs import load_job, parse_names, parse_sample, spread


def test_sample_specs():
    assert parse_sample("city") == ("city", False, False)
    assert parse_sample("city-small-joined") == ("city", True, True)
    assert parse_sample("town-small") is None


def test_small_sample_uses_its_own_camera_path():
    """city-small has its own camera path: on the full city's, 53 of 90 frames saw nothing."""
    scene, cams, title = load_job("city-small", None)
    small = cameras_from_json(sample_scenes.default_camera_path("city", small=True))
    full = cameras_from_json(sample_scenes.default_camera_path("city"))
    assert title == "city-small" and len(cams) == len(small)
    assert all(np.array_equal(a.view, b.view) for a, b in zip(cams, small, strict=True))
    assert not all(np.array_equal(a.view, b.view) for a, b in zip(cams, full, strict=True))
    with Culler(scene, (160, 90), strategy="vfc") as c:
        seen = np.array([c.truth(cam).sum() for cam in cams])
    assert (seen > 0).all(), np.flatnonzero(seen == 0)


def test_spread_and_names():
    assert spread(list(range(10)), None) == list(range(10))
    assert spread(list(range(10)), 3) == [0, 3, 6]
    assert spread(list(range(2)), 5) == [0, 1]
    assert parse_names(" vfc , om ", ("vfc", "om"), "strategies") == ["vfc", "om"]
    with pytest.raises(OccError, match="no strategies"):
        parse_names(" , ", ("vfc",), "strategies")
