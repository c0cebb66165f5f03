"""What a pass never hides, and what analyze counts as seen beyond the engine's
answer (occ_addon/policy.py, shading.py), in real Blender: the user's hides, dynamic
objects, instances, wire / bounds / in-front display, NaN values, the exclusion
collection, ray tracing, X-ray and shadows."""

import pytest

from .checks import CHECKS
from .harness import assert_check, needs_bpy

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["policy"])
def test_never_hidden_rule_holds(case_run, name):
    assert_check(case_run[0], name)
