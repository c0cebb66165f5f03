"""Live mode (occ_addon/live.py) headless: re-culls after every change (its timer driven
by hand), survives undo and reload, and shows what a moving scene camera would see
hidden before the frame is drawn."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["live"])
def test_live_mode_follows_changes(case_run, name):
    assert_check(case_run[0], name)
