"""Baked shots (occ_addon/bake.py) in real Blender: the bake, playback in any order,
renames, a save and reload, edits after the bake (a stale bake hides nothing)."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["bake"])
def test_baked_shot_holds(case_run, name):
    assert_check(case_run[0], name)
