"""The run of the cases inside Blender itself: none crashed, every check it recorded is
one a test module reports, and the interpreter exits quietly."""

from .checks import CHECKS
from .harness import needs_bpy

pytestmark = needs_bpy


def test_no_case_crashed(case_run):
    crashed = {k: v for k, v in case_run[0].items() if k.endswith("_crashed")}
    assert not crashed, crashed


def test_every_recorded_check_is_reported(case_run):
    """A check the cases record but no test module lists would pass unseen."""
    listed = {n for names in CHECKS.values() for n in names}
    unlisted = sorted(k for k in case_run[0] if k not in listed and not k.endswith("_crashed"))
    assert not unlisted, unlisted


def test_headless_exit_is_quiet(case_run):
    """A headless script that culled exits without a traceback (unregister at exit)."""
    err = case_run[1].stderr
    assert "cannot schedule new futures" not in err and "Exception in module unregister" not in err, err[-3000:]
