"""Analyze (occ_addon/analysis.py) in real Blender: the report's path and progress, the
never-visible collection (exact, excluded everywhere, undo-safe)."""

import subprocess

import pytest

from .checks import ALONE, CHECKS
from .harness import CASES, PYTHON, ROOT, assert_check, needs_bpy, run_script

pytestmark = needs_bpy

# Cases whose steps crash Blender 4.2 without the add-on: run on Blender 5 only.
BLENDER5_ONLY = {"hair_undo_two_layers": "Blender 4.2 crashes on these steps without the add-on "
                                         "(tools/repro/blender42_hair_undo_crash.py)"}


def bpy_major():
    p = subprocess.run([PYTHON, "-c", "import bpy; print(bpy.app.version[0])"], capture_output=True, text=True,
                       timeout=120)
    return int(p.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("name", CHECKS["analysis"])
def test_analysis_report_holds(case_run, name):
    assert_check(case_run[0], name)


@pytest.mark.parametrize("case", sorted(ALONE))
def test_case_that_once_crashed_blender_is_safe(tmp_path, case):
    if case in BLENDER5_ONLY and bpy_major() < 5:
        pytest.skip(BLENDER5_ONLY[case])
    """A case that once crashed Blender, in a process of its own: a crash shows as this
    test's failure (rc -11 and the output tail), not the other cases'."""
    results, p = run_script(CASES, tmp_path, ROOT, case)
    assert p.returncode == 0, (p.returncode, p.stderr[-3000:])
    missing = [n for n in ALONE[case] if n not in results]
    failed = {n: results[n] for n in ALONE[case] if n in results and not results[n][0]}
    assert not missing and not failed and not any(k.endswith("_crashed") for k in results), (missing, failed, results)
