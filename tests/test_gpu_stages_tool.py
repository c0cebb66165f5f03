"""tools/bench/gpu_stages.py: every stage of a gpu pass is timed, on the small city."""

import os
import subprocess
import sys

import pytest

from tests.cli_helpers import ROOT


@pytest.mark.skipif(os.environ.get("OCC_GL") == "4.1", reason="the gpu pass needs the 4.3 path")
def test_every_stage_is_timed():
    p = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "bench", "gpu_stages.py"), "city-small", "--empty",
                        "--resolution", "160x90"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "gpu median" in p.stdout and "vfc median" in p.stdout
    for stage in ("params", "prepare", "draw 1", "pyramid", "second", "box test 1", "third", "draw 2",
                  "box test 2", "final", "read"):
        assert f"  {stage}" in p.stdout, stage
