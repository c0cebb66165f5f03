"""The hide record (occ_addon/visibility.py) in real Blender: a user's show, then hide,
of an object the add-on hid is the user's hide; Restore and passes leave it."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["visibility"])
def test_user_owns_every_hide(case_run, name):
    assert_check(case_run[0], name)
