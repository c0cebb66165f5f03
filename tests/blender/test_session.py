"""The engine's lifecycle (occ_addon/session.py, extract.py) in real Blender: objects
known by identity, not name; edits seen, reported or not; a modal build stopped
leaves nothing behind; a click gives a new engine's answer; the fast preset keeps
what the display shows."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["session"])
def test_engine_follows_the_scene(case_run, name):
    assert_check(case_run[0], name)
