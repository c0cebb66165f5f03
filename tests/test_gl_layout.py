"""The contract between Python and the gpu pass's GLSL (core/gl/layout.py): one
definition, and tests that fail when the two sides disagree -- every field of the
records and of the parameter block read back on the GPU where Python wrote it by name,
no ``.glsl`` file defining a name the layout owns, and the guard in GLSL equal to the
engine's ``CullPass.guard`` on the same boxes.

The GPU tests run on the 4.3 path (compute shaders, float64) and skip elsewhere; every
test that takes ``ctx`` is bracketed by a GL-error check (tests/conftest.py).
"""

import glob
import os
import re

import numpy as np
import pytest

from core import Culler, Visibility
from core.gl import layout as L
from core.gl import shaders
from core.tolerance import tol
from tests import scenes

OUT_BINDING = 7                     # past the layout's bindings (1-6)


def need_43(ctx):
    if ctx.version_code < 430 or os.environ.get("OCC_GL") == "4.1":
        pytest.skip("compute shaders and float64 storage buffers are on the 4.3 path")


def compute(ctx, text):
    return ctx.compute_shader(f"{shaders.VERSION['4.3']}\n{shaders.expand(text)}")


def fill(struct, k, start):
    """``k`` records of ``struct`` whose every element is a distinct value (uints
    start + i, float32 fields i + 0.25, float64 fields i + 1/3: not a float32)."""
    rec = struct.zeros(k)
    at = start
    for f in struct.fields:
        col = rec[f.name]
        n = col.size
        values = np.arange(at, at + n, dtype=np.float64).reshape(col.shape)
        at += n
        kind = L.GLSL_TYPES[f.glsl][0]
        rec[f.name] = values if kind == "<u4" else values + (0.25 if kind == "<f4" else 1.0 / 3.0)
    return rec


def reads(struct, prefix):
    """GLSL expressions of every element of a ``struct`` record in numpy's order."""
    out = []
    for f in struct.fields:
        scalar, shape, _ = L.GLSL_TYPES[f.glsl]
        shape = ((f.count,) if f.count else ()) + shape
        out += [f"{prefix}{f.name}" + "".join(f"[{i}]" for i in idx) for idx in np.ndindex(*shape)]
    return out


def flat(rec):
    return np.concatenate([np.asarray(rec[name], dtype=np.float64).ravel() for name in rec.dtype.names])


def test_std430_offsets_follow_the_rules():
    """Members at multiples of their base alignment (dvec3 and dmat4 at 32, mat4 at 16,
    scalar arrays at their scalar's), the size a multiple of the largest; arrays with
    padding between elements are refused (numpy could not write them)."""
    s = L.Struct("S", [L.Field("a", "uint", 3), L.Field("b", "dvec3"), L.Field("c", "double"),
                       L.Field("d", "mat4"), L.Field("e", "float")])
    assert s.offsets == {"a": 0, "b": 32, "c": 56, "d": 64, "e": 128} and s.size == 160
    assert s.dtype.itemsize == 160 and s.dtype.fields["d"][1] == 64
    with pytest.raises(ValueError, match="padding"):
        L.Struct("T", [L.Field("v", "dvec3", 2)])
    assert (L.UNIT.size, L.DYN.size) == (192, 96)
    # the box tests' indirect commands 20 bytes apart (moderngl's stride), the second's instance count at 24
    assert L.PARAMS.offsets["test1_cmd"] == 0 and L.PARAMS.offsets["test2_cmd"] == 20


def test_status_bits_are_distinct_and_the_state_is_visibility():
    assert (L.STATE_VISIBLE, L.STATE_OCCLUDED, L.STATE_VIEW_CULLED) == \
        (Visibility.VISIBLE, Visibility.OCCLUDED, Visibility.VIEW_CULLED)
    flags = [L.INF, L.NEAR, L.DRAWN1, L.DRAWN2, L.TESTED1, L.TESTED2, L.PREV, L.HIZ]
    assert all(f & (f - 1) == 0 for f in flags) and len(set(flags)) == len(flags)
    assert all(f & L.STATE == 0 for f in flags) and max(Visibility) <= L.STATE


def test_no_glsl_file_defines_a_name_the_layout_owns():
    """The layout's names are defined by its generated text only: a ``.glsl`` file that
    ``#define``s one, declares one of its structs or buffers, or indexes a parameter
    array by number (the old ``f[44]``) fails here."""
    owned = L.owned_names()
    files = glob.glob(os.path.join(shaders.GLSL_DIR, "*.glsl"))
    assert len(files) >= 10                  # the glob found the shader folder
    for path in files:
        text = open(path, encoding="utf-8").read()
        name = os.path.basename(path)
        defined = set(re.findall(r"^\s*#define\s+(\w+)", text, re.MULTILINE))
        declared = set(re.findall(r"\b(?:struct|buffer)\s+(\w+)", text))
        assert not (defined | declared) & owned, f"{name} defines {(defined | declared) & owned}"
        assert not re.search(r"\b(f|hdr)\[\d+\]", text), f"{name} indexes parameters by number"
        for inc in re.findall(r'^#include "([^"]+)"', text, re.MULTILINE):
            assert inc in L.GENERATED or os.path.exists(os.path.join(shaders.GLSL_DIR, inc)), (name, inc)


def test_every_field_reads_back_where_python_wrote_it(ctx):
    """Python writes the parameter block, a Unit record and a Dyn record by field name
    (every element a distinct value); a compute shader declared by the generated layout
    copies each element, by field name, to an output buffer: the same values in the
    same order, so both sides agree on every offset, type and matrix order."""
    need_43(ctx)
    params = fill(L.PARAMS, 1, 1)[0]
    units = fill(L.UNIT, 2, 1000)
    dyns = fill(L.DYN, 2, 2000)
    exprs = reads(L.PARAMS, "P.") + reads(L.UNIT, "units[1].") + reads(L.DYN, "dyn[1].")
    body = "\n".join(f"    o[{i}] = double({e});" for i, e in enumerate(exprs))
    cs = compute(ctx, f"""#include "layout/gpucull.glsl"
layout(local_size_x = 1) in;
layout(std430, binding = {OUT_BINDING}) buffer Out {{ double o[]; }};
void main() {{
{body}
}}
""")
    bufs = {"params": ctx.buffer(params.tobytes()), "units": ctx.buffer(units.tobytes()),
            "dyns": ctx.buffer(dyns.tobytes())}
    out = ctx.buffer(reserve=8 * len(exprs))
    for name, buf in bufs.items():
        buf.bind_to_storage_buffer(L.BINDINGS[name])
    out.bind_to_storage_buffer(OUT_BINDING)
    cs.run(1)
    got = np.frombuffer(out.read(), dtype=np.float64)
    expect = np.concatenate([flat(params), flat(units[1]), flat(dyns[1])])
    assert len(expect) == len(exprs)
    bad = np.flatnonzero(got != expect)
    assert not len(bad), [(exprs[i], got[i], expect[i]) for i in bad[:5]]
    for o in (cs, out, *bufs.values()):
        o.release()


def guard_boxes(rng, k=400):
    """Camera-relative boxes ``(k, 2, 3)``: near and far, around the eye, across an
    axis, thin and flat, a point."""
    centre = rng.normal(size=(k, 3)) * rng.choice([0.5, 5.0, 50.0, 400.0], size=(k, 1))
    half = np.abs(rng.normal(size=(k, 3))) * rng.choice([0.0, 0.01, 1.0, 20.0], size=(k, 1))
    half[::7, 2] = 0.0                                       # flat
    boxes = np.stack([centre - half, centre + half], axis=1)
    boxes[0] = [(-1, -1, -1), (1, 1, 1)]                     # around the eye
    boxes[1] = [(2, 3, 4), (2, 3, 4)]                        # a point
    return boxes


@pytest.mark.parametrize("view", ["perspective", "orthographic"])
def test_the_gpu_guard_is_the_engines(ctx, view):
    """The guard the gpu pass applies (glsl/guard.glsl, with the parameters GpuCull
    writes by name) and the engine's ``CullPass.guard`` grow the same boxes by the same
    amounts (float64 on both sides: within a few ulps)."""
    need_43(ctx)
    from core.cull.view_pass import CullPass
    from core.gl.gpucull import GpuCull
    scene, cams, _ = scenes.random_city(3, 60)
    cam = cams[0] if view == "perspective" else scenes.cam(
        (-10, 0, 0.01), (0, 0, 0.01), up=(0, 0, 1), aspect=4 / 3, near=0.5, far=100, ortho_height=12.0)
    boxes = guard_boxes(np.random.default_rng(5))
    k = len(boxes)
    with Culler(scene, (64, 48), strategy="vfc", ctx=ctx) as c:
        cp = CullPass(c.hierarchy, c.renderer, cam, c.options, c.scene_size)
        assert cp.perspective == (view == "perspective")
        expect = cp.guard(boxes)
        pixels = max(cp.options.pixel_guard, tol.query_guard_px, cp.reduce_guard_px)
        gpu = GpuCull(c.renderer)
        params = gpu.params_block(cp, pixels)
        params["n_units"] = k
        cs = compute(ctx, f"""#include "cull_unit.glsl"
#include "guard.glsl"
layout(std430, binding = {OUT_BINDING}) buffer Boxes {{ double b[]; }};
layout(std430, binding = {OUT_BINDING + 1}) buffer Grown {{ double g[]; }};
void main() {{
    EACH_UNIT
    dvec3 lo = dvec3(b[6u * u], b[6u * u + 1u], b[6u * u + 2u]);
    dvec3 hi = dvec3(b[6u * u + 3u], b[6u * u + 4u], b[6u * u + 5u]);
    dvec3 r = guard(lo, hi);
    g[3u * u] = r.x; g[3u * u + 1u] = r.y; g[3u * u + 2u] = r.z;
}}
""")
        pbuf = ctx.buffer(params.tobytes())
        bbuf = ctx.buffer(np.ascontiguousarray(boxes, dtype=np.float64).tobytes())
        gbuf = ctx.buffer(reserve=8 * 3 * k)
        pbuf.bind_to_storage_buffer(L.BINDINGS["params"])
        bbuf.bind_to_storage_buffer(OUT_BINDING)
        gbuf.bind_to_storage_buffer(OUT_BINDING + 1)
        cs.run(-(-k // L.LOCAL))
        got = np.frombuffer(gbuf.read(), dtype=np.float64).reshape(k, 3)
        for o in (cs, pbuf, bbuf, gbuf):
            o.release()
        gpu.release()
    assert (expect > 0).all()
    np.testing.assert_allclose(got, expect, rtol=1e-13, atol=0)
