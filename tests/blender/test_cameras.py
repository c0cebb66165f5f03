"""The cameras of a pass (occ_addon/cameras.py) in real Blender: the scene camera as it
renders (scale ignored, mirrored, shifted), refused with a report where it cannot be
culled for."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["cameras"])
def test_camera_as_blender_draws_it(case_run, name):
    assert_check(case_run[0], name)
