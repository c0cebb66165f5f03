import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


@pytest.fixture(scope="session")
def gl_session():
    """One EGL context for the whole run (contexts are slow to make on llvmpipe)."""
    from core.gl import create_context

    ctx = create_context()
    yield ctx
    ctx.release()


@pytest.fixture
def ctx(gl_session):
    """The shared context, bracketed by a GL-error check as moderngl's own tests do."""
    assert gl_session.error == "GL_NO_ERROR"
    yield gl_session
    assert gl_session.error == "GL_NO_ERROR"
