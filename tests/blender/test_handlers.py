"""Blender's handlers (occ_addon/handlers.py) in real Blender: a file saved while culled
opens shown without the add-on; an old file that carries a record is restored on
load and when the add-on is enabled."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["handlers"])
def test_no_file_carries_the_addons_hiding(case_run, name):
    assert_check(case_run[0], name)
