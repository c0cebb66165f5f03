"""A GPU-resident culling pass (the ``gpu`` strategy's GL side; 4.3 path only).

Every draw unit's world box and world matrix live on the GPU (float64, uploaded by
:meth:`GpuCull.upload` after a rebuild or ``set_matrices``); a pass is a few
compute dispatches and indirect draws whose commands the GPU writes, and ONE
read-back of a word per unit:

1. ``prepare`` (compute, one thread per unit): frustum test of the camera-relative
   box (float64, the CPU's rule and tolerance), the query box grown by the engine's
   guard (:meth:`core.cull.view_pass.CullPass.guard`: half a query pixel + 2 depth steps,
   more where the options ask), the near-plane rule.  Last pass's visible units and
   those whose grown box reaches the near plane (visible by rule) get
   ``instanceCount = 1`` in the pass-1 commands and their MVP (float64
   camera-relative, then float32: the renderer's precision rule); every other unit
   of the frustum is marked for test 1.
2. pass 1: ONE ``glMultiDrawElementsIndirect`` over all units (0 instances for the
   others).
3. ``pyramid`` (compute, one dispatch): levels 1 and 2 of a max-depth pyramid (4 x 4
   and 16 x 16 pixels a texel) over pass 1's query-resolution depth (reduced first
   where ``display=`` is larger).
4. ``second`` (compute), test 1: each marked unit's grown box is projected (float64),
   its pixel rectangle rounded outward, and its nearest depth compared with the
   farthest depth of the rectangle at the finest level where it spans at most
   ``HIZ_SPAN`` texels (ties, and one 24-bit step, count as visible); those that
   pass join a list whose boxes are drawn in ONE instanced draw (instance count
   written by the GPU) against the same depth, early depth test ``<=`` as the
   renderer's queries, each passing fragment setting its unit's flag (the pyramid
   rejects cheaply, the rasterised box is exact on its outline).
5. ``third`` (compute): units whose box passed both get ``instanceCount = 1`` in the
   pass-2 commands and their MVP; every unit drawn (pass 1 or 2) and not near joins
   the list of test 2.  Pass 2: ONE multi-draw; test 2: that list's boxes in one
   draw against the completed depth.
6. ``final`` (compute): the state of each unit (VIEW_CULLED outside the frustum;
   VISIBLE when near or when its box passed test 2; else OCCLUDED, since it
   failed a test against real geometry) and the memory for the next pass.

Conservative by construction: a unit is OCCLUDED only when its grown box failed a
test against depth that real geometry wrote (test 1 for those never drawn, test 2
for those drawn); the memory only chooses what is drawn first.  A steady pass makes
27 GL calls (30 with ``display=``) and one blocking read, whatever the scene's size.

The shaders are ``core/gl/glsl/{prepare,pyramid,second,third,final}.comp.glsl`` and
``box_test.{vert,frag}.glsl``; their records, parameter block, status bits and bindings
come from :mod:`core.gl.layout`, which Python writes by field name.  The renderer is
used through its public hooks only (:meth:`~core.gl.renderer.BaseRenderer.count_gl`,
``use_draw_target``, ``use_query_target``, ``mark_drawn``, ``reduce``,
``attachment``).
"""

import numpy as np

from ..tolerance import tol
from . import shaders

# The status bits, re-exported (the strategy reads them from core.gl.layout)
from .layout import (  # noqa: F401
    BINDINGS,
    DEPTH_UNIT,
    DRAWN1,
    DRAWN2,
    DYN,
    FLAG1_AT,
    FLAG2_AT,
    GUARD_TINY,
    HIZ,
    INF,
    LIST1_AT,
    LIST2_AT,
    LOCAL,
    NEAR,
    PARAMS,
    PREV,
    STATE,
    TESTED1,
    TESTED2,
    UNIT,
    WORD_ARRAYS,
)

ALL_BARRIERS = 0xFFFFFFFF
ATTACHMENT = "gpu_cull"                    # the renderer attachment's key
PREPARE, PYRAMID, SECOND, THIRD, FINAL = (f"{name}.comp.glsl" for name in
                                          ("prepare", "pyramid", "second", "third", "final"))
BOX_TEST = ("box_test.vert.glsl", "box_test.frag.glsl")


def _nothing(_stage):
    pass


def for_renderer(renderer):
    """``(GpuCull, None)`` for a 4.3 renderer (made once per renderer, attached to it and
    shared by the strategies that use it: the shaders compile once), or ``(None,
    reason)`` where the driver refuses the shaders (float64 in compute shaders is
    required)."""
    import moderngl
    try:
        return renderer.attachment(ATTACHMENT, GpuCull), None
    except moderngl.Error as e:
        return None, f"the GPU culling shaders do not compile here: {e}"


class GpuCull:
    """The GPU-resident buffers and programs of the ``gpu`` strategy for one renderer
    (4.3 path).  ``units`` of the renderer; boxes from :meth:`upload`."""

    def __init__(self, renderer):
        r = self.r = renderer
        ctx = self.ctx = renderer.ctx
        r.activate()
        self.n = n = len(r.units)
        cap = max(n, 1)
        self._compile()
        r.depth_tex.compare_func = ""                  # texelFetch reads depth values
        size = np.array([r.width, r.height])
        levels = [(size + 3) // 4]
        levels.append((levels[-1] + 3) // 4)
        self.levels = [(int(a), int(b)) for a, b in levels]
        self.pyramid_groups = tuple(int(v) for v in (levels[-1] + 7) // 8)     # 128 x 128 pixels a group
        self.hiz = ctx.buffer(reserve=4 * int(sum(int(a * b) for a, b in levels)))
        self.params = ctx.buffer(reserve=PARAMS.size)
        self.unit_buf = ctx.buffer(reserve=UNIT.size * cap)
        self.dyn = ctx.buffer(reserve=DYN.size * cap)
        self.words = ctx.buffer(reserve=4 * len(WORD_ARRAYS) * cap)
        self.words.clear()
        # commands of pass 1 at [0, n), of pass 2 at [n, 2n): the renderer's, baseInstance = unit
        cmds = np.zeros((2, cap, 5), dtype=np.uint32)
        if n:
            cmds[:, :n] = r.commands
            cmds[:, :n, 1] = 0
            cmds[:, :n, 4] = np.arange(n, dtype=np.uint32)
        self.cmds = ctx.buffer(cmds.tobytes())
        # the pass draws take each unit's MVP from its Dyn record, whose first field it is
        # (baseInstance = unit)
        per_unit = f"16f {DYN.size - DYN.offsets['glo']}x/i"
        self.draw_vao = ctx.vertex_array(r.depth_prog, [(r.vbo, "3f", "in_pos"), (self.dyn, per_unit, "in_mvp")],
                                         index_buffer=r.ibo, index_element_size=4)
        self.box_vaos = [ctx.vertex_array(p, []) for p in self.box_progs]
        self.groups = max(1, -(-n // LOCAL))
        self.uploaded = False

    def _compile(self):
        """The five compute passes and the two box-test programs (list and flag arrays
        of test 1 and of test 2)."""
        ctx = self.ctx

        def compute(name):
            return ctx.compute_shader(shaders.source(name, "4.3"))

        def box_test(list_at, flag_at):
            defines = {"LIST": f"{list_at}u", "FLAG": f"{flag_at}u"}
            return ctx.program(vertex_shader=shaders.source(BOX_TEST[0], "4.3", defines),
                               fragment_shader=shaders.source(BOX_TEST[1], "4.3", defines))

        self.prepare = compute(PREPARE)
        self.pyramid = compute(PYRAMID)
        self.second = compute(SECOND)
        self.third = compute(THIRD)
        self.final = compute(FINAL)
        for cs in (self.pyramid, self.second):
            cs["u_depth"].value = DEPTH_UNIT
        self.box_progs = [box_test(LIST1_AT, FLAG1_AT), box_test(LIST2_AT, FLAG2_AT)]

    def upload(self, boxes, valid, world, units=None):
        """World boxes ``(k, 2, 3) float64``, ``valid (k,) bool`` and world matrices of
        the units' objects (mesh centre folded in) ``(k, 4, 4) float64`` of ``units``
        (default all, ``k = n``): one write per run of consecutive units."""
        units = np.arange(self.n) if units is None else np.asarray(units, dtype=np.int64)
        k = len(units)
        if not k:
            return
        ok = valid & np.isfinite(boxes).all(axis=(1, 2)) & (boxes[:, 0] <= boxes[:, 1]).all(axis=1)
        rec = UNIT.zeros(k)
        rec["world"] = np.asarray(world, dtype=np.float64).transpose(0, 2, 1)      # column-major
        rec["lo"][:, :3] = np.where(ok[:, None], boxes[:, 0], 0.0)
        rec["lo"][:, 3] = ok                                                       # w: valid
        rec["hi"][:, :3] = np.where(ok[:, None], boxes[:, 1], 0.0)
        self.r.activate()
        starts = np.flatnonzero(np.r_[True, np.diff(units) != 1])
        for a, b in zip(starts, np.r_[starts[1:], k], strict=True):
            self.unit_buf.write(rec[a:b].tobytes(), offset=UNIT.size * int(units[a]))
        self.r.count_gl(len(starts))
        self.uploaded = True

    def remember(self, visible):
        """Set the memory (what pass 1 draws) to ``visible (n,) bool``: one write."""
        self.r.activate()
        self.words.write(np.where(visible, PREV, 0).astype(np.uint32).tobytes())
        self.r.count_gl()

    def forget(self):
        self.remember(np.zeros(self.n, dtype=bool))

    def params_block(self, frame, pixels):
        """The per-pass parameters (:data:`core.gl.layout.PARAMS`, field by field): the
        box-test commands (36 vertices, instances counted by the GPU), the unit count,
        the view-projection in float32 and float64, and the guard's values
        (:meth:`core.cull.view_pass.CullPass.guard` with ``pixels`` query pixels)."""
        r = self.r
        p = PARAMS.zeros()
        p["test1_cmd"][0] = p["test2_cmd"][0] = 36
        p["n_units"] = self.n
        p["vp"] = r.clip.T                             # column-major, then float32
        p["eye"] = r.eye
        p["clip"] = r.clip.T
        p["planes"] = frame.planes
        p["plane_rel"] = tol.plane_rel
        p["near_rel"] = tol.near_guard_rel
        p["grow_rel"] = tol.box_grow_rel
        p["grow_abs"] = tol.box_grow_scene * frame.scene_size
        p["lateral"] = pixels * frame.pixel_world
        p["perspective"] = 1.0 if frame.perspective else 0.0
        p["tie"] = tol.depth_guard_steps * frame.depth_step
        p["extent"] = r.view_extent
        p["tiny"] = GUARD_TINY
        p["dir"] = np.abs(frame.camera.direction)
        return p

    def run(self, frame, pixels, stage=None):
        """One pass from the frame's camera (the renderer's ``begin_frame`` done):
        returns the word of every unit, ``(n,) uint32`` (module doc).  ``stage``:
        called with each stage's name once its GL work is issued (a profiler's hook,
        tools/bench/gpu_stages.py)."""
        r, ctx, n = self.r, self.ctx, self.n
        done = stage or _nothing
        r.activate()
        self.params.write(self.params_block(frame, pixels).tobytes())
        self.bind()
        done("params")
        self.prepare.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        r.count_gl(9)                          # params, 6 bindings, dispatch, barrier
        done("prepare (frustum, guard)")
        self._draw(0)
        done("draw 1 (last visible)")
        self.build_pyramid()
        done("pyramid")
        self.second.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        r.count_gl(5)
        done("second (pyramid test)")
        self._test(0)                          # pass 1's depth: reduced already
        done("box test 1")
        self.third.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        r.count_gl(2)
        done("third")
        self._draw(n)
        done("draw 2 (newly visible)")
        self._test(1)
        done("box test 2")
        self.final.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        done("final")
        words = np.frombuffer(self.words.read(size=4 * n), dtype=np.uint32)
        r.count_gl(3, reads=1, batches=3)
        done("read")
        return words

    def bind(self):
        """Bind the storage buffers at their layout binding points (the renderer's queries use 0)."""
        for name, buf in (("params", self.params), ("units", self.unit_buf), ("dyns", self.dyn),
                          ("words", self.words), ("cmds", self.cmds), ("hiz", self.hiz)):
            buf.bind_to_storage_buffer(BINDINGS[name])

    def build_pyramid(self):
        """Levels 1 and 2 of the max-depth pyramid from the query-resolution depth (bound)."""
        self.r.depth_tex.use(DEPTH_UNIT)
        self.pyramid.run(*self.pyramid_groups)
        self.ctx.memory_barrier(ALL_BARRIERS)

    def read_pyramid(self):
        """Levels 1 and 2, ``[(h1, w1) float32, (h2, w2) float32]`` (row 0 at the bottom): the
        farthest depth of the 4 x 4 and 16 x 16 pixels each texel covers (an analyzer)."""
        data = np.frombuffer(self.hiz.read(), dtype=np.float32)
        out, at = [], 0
        for w, h in self.levels:
            out.append(data[at:at + w * h].reshape(h, w))
            at += w * h
        return out

    def _draw(self, first):
        """Pass 1 (``first = 0``) or pass 2 (``first = n``): one multi-draw whose instance
        counts the compute passes wrote; then, with a larger display, the whole query
        depth reduced (what the GPU drew is not known here)."""
        r = self.r
        r.use_draw_target()
        self.draw_vao.render_indirect(self.cmds, count=self.n, first=first)
        r.count_gl(1, draws=1)
        if r.reduces:
            r.mark_drawn()
            r.reduce()

    def _test(self, k):
        r = self.r
        r.use_query_target()
        self.box_vaos[k].render_indirect(self.params, mode=self.ctx.TRIANGLES, count=1, first=k)
        # the flags written by the boxes' fragments before the compute pass that reads them
        self.ctx.memory_barrier(ALL_BARRIERS)
        r.count_gl(2, draws=1)

    def release(self):
        for o in (*self.box_vaos, self.draw_vao, self.prepare, self.pyramid, self.second, self.third, self.final,
                  *self.box_progs,
                  self.params, self.unit_buf, self.dyn, self.words, self.cmds, self.hiz):
            o.release()
