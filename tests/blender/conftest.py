"""The cases inside Blender run once for the whole session, in subprocesses that share
them (bpy must not share a process with the moderngl tests), against the zip built by
Blender's own extension CLI; each test module reports the checks of its home."""

import pytest

from .harness import CASES, ROOT, run_sharded


@pytest.fixture(scope="session")
def case_run(tmp_path_factory):
    """``(results, completed process)`` of every case of ``cases.CASES``, shared by the
    harness's processes (:func:`.harness.run_sharded`)."""
    return run_sharded(CASES, tmp_path_factory.mktemp("blender_cases"), ROOT)
