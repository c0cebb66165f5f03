"""Hiding in one 3D view (occ_addon/localview.py) in real Blender: another view draws
everything, the view and the selection stay the user's, new objects, undo, files and the
user's own local view keep every visible object drawn."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["localview"])
def test_hiding_in_one_view(case_run, name):
    assert_check(case_run[0], name)
