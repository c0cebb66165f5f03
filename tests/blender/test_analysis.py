"""Analyze (occ_addon/analysis.py) in real Blender: the report's path and progress, the
never-visible collection (exact, excluded everywhere, undo-safe)."""

import pytest

from .checks import ALONE, CHECKS
from .harness import CASES, ROOT, assert_check, needs_bpy, run_script

pytestmark = needs_bpy


@pytest.mark.parametrize("name", CHECKS["analysis"])
def test_analysis_report_holds(case_run, name):
    assert_check(case_run[0], name)


@pytest.mark.parametrize("case", sorted(ALONE))
def test_case_that_once_crashed_blender_is_safe(tmp_path, case):
    """A case that once crashed Blender, in a process of its own: a crash shows as this
    test's failure (rc -11 and the output tail), not the other cases'."""
    results, p = run_script(CASES, tmp_path, ROOT, case)
    assert p.returncode == 0, (p.returncode, p.stderr[-3000:])
    missing = [n for n in ALONE[case] if n not in results]
    failed = {n: results[n] for n in ALONE[case] if n in results and not results[n][0]}
    assert not missing and not failed and not any(k.endswith("_crashed") for k in results), (missing, failed, results)
