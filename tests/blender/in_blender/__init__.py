"""The cases run inside Blender by ``tests/blender/cases.py``, one module per home of
the add-on (``occ_addon/``): :mod:`.policy`, :mod:`.cameras`, :mod:`.session`,
:mod:`.visibility`, :mod:`.handlers`, :mod:`.live`, :mod:`.analysis`; shared scene
helpers and the truth in :mod:`.common`.  Each records checks named after the
behaviour they check; ``tests/blender/checks.py`` lists them for pytest."""
