"""The contract between Python and the GLSL of the ``gpu`` strategy's pass, in one place.

Everything both sides of the GPU boundary must agree on is defined here once, and the
GLSL side is generated from it (niagara shares ``mesh.h`` between C++ and GLSL; nvpro's
culling system keeps its std430 layout in one header):

- the bits of a unit's word, the one read-back of a pass (``STATE`` ... ``HIZ``);
- the word arrays of the words buffer and the storage-buffer binding points;
- the records of the units (``UNIT``) and of their per-pass data (``DYN``) and the
  per-pass parameter block (``PARAMS``), each a std430 struct whose offsets are
  computed here by std430's rules and written by Python through a numpy structured
  dtype, field by field by name, never by index;
- the work-group size, the pyramid's span, the guard's literal constants, the box
  corner table and the depth buffer's number of levels.

:func:`glsl_include` gives the generated text that a ``.glsl`` file pulls in with
``#include "layout/<name>.glsl"`` (expanded by :mod:`core.gl.shaders`); no ``.glsl`` file
defines a name this module owns (tests/test_gl_layout.py checks both that and, on the
4.3 path, that the driver reads every field where Python writes it).

No moderngl import: the numpy engine reads the status bits from here.
"""

from dataclasses import dataclass

import numpy as np

from ..tolerance import tol

# --- a unit's word (read back once a pass) --------------------------------------------
# bits 0-1: the unit's state, core.cull.result.Visibility's values
STATE_VISIBLE, STATE_OCCLUDED, STATE_VIEW_CULLED = 0, 1, 2
STATE = 0b11
INF = 1 << 2           # inside the frustum
NEAR = 1 << 3          # its grown box reaches the near plane: visible by rule, never tested
DRAWN1 = 1 << 4        # drawn in pass 1 (last pass's visible, or near)
DRAWN2 = 1 << 5        # drawn in pass 2 (passed both tests against pass 1's depth)
TESTED1 = 1 << 6       # tested against pass 1's depth
TESTED2 = 1 << 7       # tested against the completed depth
PREV = 1 << 8          # visible in the last pass: the memory, what pass 1 draws
HIZ = 1 << 9           # passed the pyramid test
STATUS_BITS = {"STATE_VISIBLE": STATE_VISIBLE, "STATE_OCCLUDED": STATE_OCCLUDED,
               "STATE_VIEW_CULLED": STATE_VIEW_CULLED, "STATE": STATE, "INF": INF, "NEAR": NEAR,
               "DRAWN1": DRAWN1, "DRAWN2": DRAWN2, "TESTED1": TESTED1, "TESTED2": TESTED2,
               "PREV": PREV, "HIZ": HIZ}

# --- the words buffer: arrays of n words each, in this order --------------------------
# the units' words, the box tests' flags (set by the boxes' fragments) and lists (the
# units each box test draws, appended by the compute passes)
WORD_ARRAYS = {"STATE_AT": 0, "FLAG1_AT": 1, "FLAG2_AT": 2, "LIST1_AT": 3, "LIST2_AT": 4}
STATE_AT, FLAG1_AT, FLAG2_AT, LIST1_AT, LIST2_AT = WORD_ARRAYS.values()

# --- storage-buffer binding points (the renderer's query counters use 0) -------------
BINDINGS = {"params": 1, "units": 2, "dyns": 3, "words": 4, "cmds": 5, "hiz": 6}
DEPTH_UNIT = 7         # texture unit of the depth the pyramid reads (the renderer uses 0)

LOCAL = 64             # compute work-group size (one thread per unit)
# The pyramid test reads the finest level where the box's rectangle spans at most this many
# texels a side (level 2 whatever the span): 8 drew 206 units on city-xl where 4 drew 252.
HIZ_SPAN = 8

# The guard's floors, as core.cull.view_pass.CullPass.guard reads them (core/tolerance.py).
GUARD_TINY = tol.guard_tiny
GUARD_NEAR_W_REL = tol.guard_near_w_rel
# Levels of the depth buffer (2^bits - 1): a shader's read of it may round a step nearer.
DEPTH_LEVELS = (1 << tol.depth_bits) - 1

# 12 triangles of a box, counter-clockwise seen from outside, as indices into
# bounds.corners' bit order (x=1, y=2, z=4): the CPU's box vertices and the shaders'
# corner table (box vertices expanded from gl_VertexID).
BOX_TRIANGLES = np.array([
    0, 2, 1, 1, 2, 3,   4, 5, 6, 5, 7, 6,   0, 1, 4, 1, 5, 4,
    2, 6, 3, 3, 6, 7,   0, 4, 2, 2, 4, 6,   1, 3, 5, 3, 7, 5,
], dtype=np.intp)

# --- std430 structs ----------------------------------------------------------------------
# GLSL type -> (numpy scalar, shape, std430 base alignment in bytes).  A matrix is
# column-major: its numpy field holds M.T (row i = column i).
GLSL_TYPES = {
    "uint": ("<u4", (), 4), "float": ("<f4", (), 4), "double": ("<f8", (), 8),
    "vec4": ("<f4", (4,), 16), "mat4": ("<f4", (4, 4), 16),
    "dvec3": ("<f8", (3,), 32), "dvec4": ("<f8", (4,), 32), "dmat4": ("<f8", (4, 4), 32),
}


@dataclass(frozen=True)
class Field:
    name: str
    glsl: str                 # a key of GLSL_TYPES
    count: int = 0            # 0: not an array
    doc: str = ""

    @property
    def size(self):
        scalar, shape, _ = GLSL_TYPES[self.glsl]
        return np.dtype(scalar).itemsize * int(np.prod(shape, dtype=np.int64))

    @property
    def align(self):
        return GLSL_TYPES[self.glsl][2]


class Struct:
    """A std430 struct: ``fields`` in order; ``offsets`` by std430's rules (each member
    at a multiple of its base alignment, the struct's size a multiple of its largest);
    ``dtype``, the numpy structured dtype with those offsets; :meth:`glsl`, its
    declaration."""

    def __init__(self, name, fields):
        self.name, self.fields = name, tuple(fields)
        at, offsets = 0, {}
        for f in self.fields:
            if f.count and f.size % f.align:
                raise ValueError(f"{name}.{f.name}: arrays of {f.glsl} have padding between elements")
            at = -(-at // f.align) * f.align
            offsets[f.name] = at
            at += f.size * max(f.count, 1)
        self.align = max(f.align for f in self.fields)
        self.size = -(-at // self.align) * self.align
        self.offsets = offsets
        formats = []
        for f in self.fields:
            scalar, shape, _ = GLSL_TYPES[f.glsl]
            shape = ((f.count,) if f.count else ()) + shape
            formats.append((scalar, shape) if shape else scalar)
        self.dtype = np.dtype({"names": [f.name for f in self.fields], "formats": formats,
                               "offsets": [offsets[f.name] for f in self.fields], "itemsize": self.size})

    def members(self):
        """The member declarations, one a line."""
        return "".join(f"    {f.glsl} {f.name}{f'[{f.count}]' if f.count else ''};"
                       f"{f'  // {f.doc}' if f.doc else ''}\n" for f in self.fields)

    def glsl(self):
        return f"struct {self.name} {{\n{self.members()}}};\n"

    def zeros(self, shape=()):
        return np.zeros(shape, dtype=self.dtype)


# A unit's world box and matrix (uploaded after a rebuild or a move).
UNIT = Struct("Unit", [Field("world", "dmat4", doc="world matrix, mesh centre folded in"),
                       Field("lo", "dvec4", doc="world box min; w: 1 valid, 0 never drawn nor tested"),
                       Field("hi", "dvec4", doc="world box max")])
# A unit's per-pass data, written by the compute passes.
DYN = Struct("Dyn", [Field("mvp", "mat4", doc="camera-relative MVP, float64 then float32"),
                     Field("glo", "vec4", doc="grown camera-relative box min (clamped to the view extent)"),
                     Field("ghi", "vec4", doc="grown camera-relative box max")])
# The per-pass parameters; the two box-test commands first (moderngl reads indirect
# commands 20 bytes apart: DrawArraysIndirectCommand and a word of padding).
PARAMS = Struct("Params", [
    Field("test1_cmd", "uint", 5, "box test 1's draw: 36 vertices, instances counted by the GPU"),
    Field("test2_cmd", "uint", 5, "box test 2's draw"),
    Field("n_units", "uint"),
    Field("vp", "mat4", doc="float32 camera-relative view-projection (the box tests')"),
    Field("eye", "dvec3"),
    Field("clip", "dmat4", doc="camera-relative view-projection"),
    Field("planes", "dvec4", 6, "frustum planes (core.frustum order; 4 is the near plane)"),
    Field("plane_rel", "double", doc="tol.plane_rel"),
    Field("near_rel", "double", doc="tol.near_guard_rel"),
    Field("grow_rel", "double", doc="tol.box_grow_rel"),
    Field("grow_abs", "double", doc="tol.box_grow_scene x scene size"),
    Field("lateral", "double", doc="guard pixels x world size of a pixel"),
    Field("perspective", "double", doc="1 perspective, 0 orthographic"),
    Field("tie", "double", doc="tol.depth_guard_steps x eye-space depth step"),
    Field("extent", "double", doc="half-size of the cube about the eye that holds the frustum"),
    Field("tiny", "double", doc="GUARD_TINY"),
    Field("dir", "dvec3", doc="|view direction| (orthographic guard)"),
])


def _defines(table, suffix="u"):
    return "".join(f"#define {k} {v}{suffix}\n" for k, v in table.items())


def _gpucull_glsl():
    """Defines, structs and storage buffers of the gpu pass's shaders."""
    b = BINDINGS
    return (_defines(STATUS_BITS) + _defines(WORD_ARRAYS)
            + f"#define LOCAL {LOCAL}\n#define HIZ_SPAN {HIZ_SPAN}\n"
            + f"#define GUARD_NEAR_W_REL {GUARD_NEAR_W_REL!r}lf\n"
            + UNIT.glsl() + DYN.glsl()
            + f"layout(std430, binding = {b['params']}) buffer Params {{\n{PARAMS.members()}}} P;\n"
            + f"layout(std430, binding = {b['units']}) readonly buffer Units {{ Unit units[]; }};\n"
            + f"layout(std430, binding = {b['dyns']}) buffer Dyns {{ Dyn dyn[]; }};\n"
            + f"layout(std430, binding = {b['words']}) buffer Words {{ uint w[]; }};\n"
            + f"layout(std430, binding = {b['cmds']}) buffer Cmds {{ uint c[]; }};\n"
            # levels 1 and 2 of the max-depth pyramid (level 0 is the depth texture)
            + f"layout(std430, binding = {b['hiz']}) buffer Hiz {{ float z[]; }};\n")


def _box_glsl():
    return f"#define BOX_CORNERS {', '.join(str(int(i)) for i in BOX_TRIANGLES)}\n"


def _depth_glsl():
    return f"#define DEPTH_LEVELS {DEPTH_LEVELS}.0\n"


GENERATED = {"layout/gpucull.glsl": _gpucull_glsl, "layout/box.glsl": _box_glsl,
             "layout/depth.glsl": _depth_glsl}


def glsl_include(name):
    """The generated GLSL text of ``#include "<name>"`` (a key of ``GENERATED``)."""
    return GENERATED[name]()


def owned_names():
    """Every name the generated GLSL defines (no ``.glsl`` file may define one again)."""
    return (set(STATUS_BITS) | set(WORD_ARRAYS)
            | {"LOCAL", "HIZ_SPAN", "GUARD_NEAR_W_REL", "BOX_CORNERS", "DEPTH_LEVELS",
               UNIT.name, DYN.name, PARAMS.name, "Units", "Dyns", "Words", "Cmds", "Hiz"})
