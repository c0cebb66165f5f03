"""The envelope pass's image work on the GPU (4.3 path only; :mod:`core.envelope`'s
numpy :func:`~core.envelope.extended_depth` is the reference, and the 4.1 path's).

From the envelope's depth texture (:meth:`~core.gl.renderer.BaseRenderer.envelope_depth`,
never read back) to the extended depth image, read back once:

1. ``envelope_breaks`` (one thread per pixel): the view-space depth of each pixel's
   first surface, and whether the pixel breaks continuity (empty, nearer than what may
   cover, or beside a depth jump: the reference's ``_jumps``, pair by pair); written
   as ``(-z, z)``, ``z = +inf`` at a break, so that a window's maximum says both its
   nearest depth and whether it holds a break.
2. ``envelope_grow``, twice per window size (rows, then columns): the window maxima of
   the next size from the last (the reference's ``_shift_max``); after the columns, each
   pixel still open whose window holds no break and holds its parallax takes the
   window's farthest depth (one buffer of the extended depth, ``+inf``: open).

The shaders compute what the reference computes in the same precision and order
(double for depths, float for the rest, no fused multiply-add), so on a driver that
rounds as IEEE says (llvmpipe) the image is the reference's, bit for bit
(``tests/test_gpu_envelope.py``); elsewhere a difference of a rounding is far inside
the margins both keep (the depth guard's steps, the parallax's ``1e-5``).
"""

import math
import os

import numpy as np

from ..errors import OccError
from . import shaders

ATTACHMENT = "gpu_envelope"          # the renderer attachment's key
BINDING = {"SRC_BINDING": 8, "DST_BINDING": 9, "EXT_BINDING": 10, "OUT_BINDING": 8}
DEPTH_UNIT = 6                       # texture unit of the envelope's depth
LOCAL = 8                            # 8 x 8 threads a group
ALL_BARRIERS = 0xFFFFFFFF
# Renderers that rasterise on the CPU: there numpy's whole-array steps beat the compute
# passes (llvmpipe, the city at 2,10: 0.77 s a pass in numpy, 1.40 s on the "GPU"; the
# grow passes cost ~40 ms each, a few ms in numpy)
SOFTWARE = ("llvmpipe", "softpipe", "swrast", "swiftshader", "software rasterizer")
CHOICES = ("auto", "gpu", "numpy")


def choice():
    """``OCC_ENVELOPE``: ``gpu`` (the compute passes wherever the 4.3 path runs), ``numpy``
    (never), unset or ``auto`` (on a hardware GPU only)."""
    want = os.environ.get("OCC_ENVELOPE", "").strip().lower() or "auto"
    if want not in CHOICES:
        raise OccError(f"OCC_ENVELOPE must be one of {', '.join(CHOICES)} (or unset), got {want!r}")
    return want


def for_renderer(renderer):
    """The renderer's :class:`GpuEnvelope` (made once, attached to it), or None where the
    path is not 4.3, :func:`choice` says numpy (``auto``: a software rasteriser), or the
    driver refuses the shaders (doubles in compute shaders)."""
    want = choice()
    if getattr(renderer, "path", None) != "4.3" or want == "numpy":
        return None
    if want == "auto" and any(k in renderer.device.lower() for k in SOFTWARE):
        return None
    import moderngl
    try:
        return renderer.attachment(ATTACHMENT, GpuEnvelope)
    except moderngl.Error:
        return None


class GpuEnvelope:
    """The two compute programs and the per-size buffers of one renderer."""

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = ctx = renderer.ctx
        renderer.activate()
        self.breaks = ctx.compute_shader(shaders.source("envelope_breaks.comp.glsl", "4.3", BINDING))
        self.grow = ctx.compute_shader(shaders.source("envelope_grow.comp.glsl", "4.3", BINDING))
        self.breaks["u_depth"].value = DEPTH_UNIT
        self.size = None
        self.buffers = ()

    def _buffers(self, w, h):
        if self.size != (w, h):
            for b in self.buffers:
                b.release()
            px = w * h
            self.buffers = (self.ctx.buffer(reserve=8 * px), self.ctx.buffer(reserve=8 * px),
                            self.ctx.buffer(reserve=4 * px))
            self.size = (w, h)
        return self.buffers

    def extended_depth(self, tex, lens, envelope, near_eff, half_sizes, slope_tolerance, nearest_guard):
        """The extended depth of the depth texture ``tex`` (the envelope's square view,
        ``lens = (near, far, tan_half)`` of its camera; window ``half_sizes`` in order;
        ``slope_tolerance(near, far)`` and ``nearest_guard``: the reference's rules):
        ``(h, w) float64``, ``inf`` open; the reference's
        :func:`core.envelope.extended_depth` (module doc)."""
        r, ctx = self.r, self.ctx
        near, far, tan_half = lens
        w, h = tex.size
        a, b, ext = self._buffers(w, h)
        r.activate()
        dt = 2.0 * tan_half / h
        distance = envelope.distance
        common = {"u_size": (w, h), "u_dt": dt, "u_cx0": 0.5 * w * dt, "u_cy0": tan_half}
        bp = self.breaks
        for k, v in {**common, "u_c1": 2.0 * near * far, "u_c2": far + near, "u_c3": far - near,
                     "u_near_eff": float(near_eff), "u_jumps": int(distance > 0.0),
                     "u_wtol": float(np.float32(slope_tolerance(near, far)))}.items():
            _set(bp, k, v)
        groups = (-(-w // LOCAL), -(-h // LOCAL))
        tex.use(DEPTH_UNIT)
        a.bind_to_storage_buffer(BINDING["OUT_BINDING"])
        ext.bind_to_storage_buffer(BINDING["EXT_BINDING"])           # the pass opens every pixel
        bp.run(*groups)
        ctx.memory_barrier(ALL_BARRIERS)
        calls = 18
        gp = self.grow
        for k, v in {**common, "u_dguard": float(np.float32(distance * nearest_guard)),
                     "u_d": float(np.float32(distance)), "u_d2": float(np.float32(distance ** 2)),
                     "u_slack": float(np.float32(1.0 + 1e-5)), "u_dt32": float(np.float32(dt))}.items():
            _set(gp, k, v)
        for half in half_sizes:
            if half >= min(w, h):
                break
            _set(gp, "u_k", (half + 1) // 2)
            _set(gp, "u_h", half)
            _set(gp, "u_diag", float(np.float32(half * dt * math.sqrt(2.0))))
            for axis, (src, dst) in enumerate(((a, b), (b, a))):
                _set(gp, "u_axis", axis)
                _set(gp, "u_eval", axis)
                src.bind_to_storage_buffer(BINDING["SRC_BINDING"])
                dst.bind_to_storage_buffer(BINDING["DST_BINDING"])
                gp.run(*groups)
                ctx.memory_barrier(ALL_BARRIERS)
                calls += 6
        out = np.frombuffer(ext.read(), dtype=np.float32).reshape(h, w)
        r.count_gl(calls + 1, reads=1)
        return out.astype(np.float64)

    def release(self):
        for o in (self.breaks, self.grow, *self.buffers):
            o.release()


def _set(prog, name, value):
    """A uniform's value, where the compiler kept it."""
    try:
        prog[name].value = value
    except KeyError:
        pass
