"""GLSL sources of both GL paths: the ``.glsl`` files of ``core/gl/glsl/``, loaded here.

A file has no ``#version`` line (:func:`source` puts the path's first) and pulls in
shared text with ``#include "name.glsl"``: another file of the folder, or, for a name
under ``layout/``, the text :mod:`core.gl.layout` generates (its defines, structs and
buffers).  Files are named ``what.stage.glsl`` (niagara's habit); included snippets
have no stage.

Conventions: positions are camera-relative (world - eye) rounded to float32 after
float64 math on the CPU; depth test ``<`` for geometry, ``<=`` for query boxes
(ties count as visible); query boxes write neither depth nor colour.
"""

import functools
import os
import re

from . import layout

VERSION = {"4.3": "#version 430 core", "4.1": "#version 410 core"}
GLSL_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "glsl")
_INCLUDE = re.compile(r'^#include "([\w./-]+)"[ \t]*$', re.MULTILINE)


@functools.cache
def read(name: str) -> str:
    """The text of ``glsl/<name>`` with its ``#include`` lines expanded."""
    with open(os.path.join(GLSL_DIR, name), encoding="utf-8") as f:
        return expand(f.read())


def expand(text: str) -> str:
    """``text`` with each ``#include "name"`` line replaced by that file's text (or the
    layout's generated text), recursively."""
    return _INCLUDE.sub(lambda m: _included(m.group(1)), text)


def _included(name):
    if name in layout.GENERATED:
        return layout.glsl_include(name)
    return read(name)


def source(name: str, path: str, defines: dict | None = None) -> str:
    """The compilable text of ``glsl/<name>`` for GL ``path`` ("4.3" or "4.1"): the
    ``#version`` line, then ``defines`` (``{name: value}``, each ``#define name value``),
    then the file."""
    head = "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
    return f"{VERSION[path]}\n{head}{read(name)}"
