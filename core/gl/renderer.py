"""Depth rendering, one-draw occlusion queries and object-ID truth on moderngl.

Meshes are uploaded once: one vertex buffer (each mesh recentred on its own box
centre, so float32 keeps its precision), one index buffer of absolute indices,
and per draw unit an index range.  Matrices are made camera-relative in float64
-- ``P @ R @ (M @ T(centre) - T(eye))`` -- and only then rounded to float32, so a
scene 1e6 units from the origin renders as well as one at it; this is done in
``draw`` for the units drawn, never for the whole scene per frame.

Two GL paths (see :mod:`core.gl.context`; ``OCC_GL=4.1`` forces the second):

- 4.3: a ``draw`` is one ``glMultiDrawElementsIndirect`` whose commands and per-draw
  MVPs go up in one buffer write (a ring of draw data, picked by baseInstance).  A
  query batch is ONE instanced draw of all its boxes (corners expanded in the vertex
  shader), early depth test ``<=``, no depth or colour write; every passing fragment
  adds one to its box's counter in a storage buffer (or, with ``counts=False``, sets
  its flag), read back once per batch; each pending batch owns its buffer.
- 4.1 (macOS): one draw per unit with a uniform MVP, one occlusion query object per
  box, one blocking read per box.

Both give the same samples per box: the samples of the box's front faces (chosen
from the sign of the view-projection's determinant, so a mirrored camera works) that
pass ``<=`` the depth buffer.  Ties count as visible; geometry is drawn with ``<``.

Query resolution and display resolution: ``GLRenderer(..., width, height,
display=(W, H))`` draws occluders at ``W x H`` and, before each query batch, reduces
them to ``width x height`` taking for every query pixel the FARTHEST depth of all
display pixels its area overlaps; queries run at ``width x height`` against that.
A gap open at display resolution therefore stays open; only the query pixels under
what was drawn since the last batch are reduced (scissor).  The boxes must be
conservative at the query resolution too: the caller grows each box by one query
pixel (measured at the box's farthest point); the renderer does not grow boxes.

``counters`` (reset by ``begin_frame``): ``gl_calls`` (draws, buffer writes and
orphans, uniform writes, query begin/end, reads, memory barriers, finish; state
toggles are set only when they change and not counted), ``blocking_reads``,
``query_fragments`` (samples passed in query draws), ``draws``, ``query_batches``.
"""

import weakref

import numpy as np

from ..bounds import corners, transform_boxes
from ..errors import OccError
from . import shaders as S
from .context import choose_path, create_context

GL_BUFFER_UPDATE_BARRIER_BIT = 0x200   # shader writes visible to buffer reads/maps
SSBO_ALIGN = 256                        # >= GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT everywhere
CMD_BYTES = 20                          # one DrawElementsIndirectCommand
# Per-draw instance record of the 4.3 stream: column-major MVP and object id.
RECORD = np.dtype([("mvp", "<f4", (16,)), ("id", "<u4")])
STREAM_ALIGN = 340                      # lcm(CMD_BYTES, RECORD.itemsize): a chunk starts on both
# GL state this package set last, per context: renderers sharing a context share it.
_CONTEXT_STATE = weakref.WeakKeyDictionary()
F32_SAFE = 1e30                         # far inside float32's range, after a projection too
NDC_CORNERS = np.array([(x, y, z, 1.0) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)])
COUNTER_KEYS = ("gl_calls", "blocking_reads", "query_fragments", "draws", "query_batches")
BOX_TRIANGLES = S.BOX_TRIANGLES


def box_vertices(boxes):
    """Triangle-list vertices of boxes: ``(k, 2, 3)`` -> ``(k * 36, 3) float32``."""
    return corners(boxes)[:, BOX_TRIANGLES].reshape(-1, 3).astype(np.float32)


def _view_extent(clip):
    """Half-size of a cube about the eye that holds the whole view frustum of ``clip``
    (camera-relative), with a margin; at most ``F32_SAFE``."""
    try:
        c = NDC_CORNERS @ np.linalg.inv(clip).T
    except np.linalg.LinAlgError:
        return F32_SAFE
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.abs(c[:, :3] / c[:, 3:]).max()
    return float(min(2.0 * r, F32_SAFE)) if np.isfinite(r) else F32_SAFE


def _ceil_to(x, m):
    return -(-x // m) * m


def _pow2(x, least=64):
    return max(least, 1 << int(np.ceil(np.log2(max(x, 1)))))


class PendingQuery:
    """A query batch issued and not read yet; :meth:`result` reads it back once.

    Draws issued in between do not change its answer: the batch owns its result
    buffer (4.3) or query objects (4.1) until it is read (or dropped unread).
    """

    __slots__ = ("_read", "_drop", "_samples")

    def __init__(self, read, drop=None):
        self._read, self._drop, self._samples = read, drop, None

    def result(self):
        """Samples passed per box, ``(k,) int64`` (0 = hidden); blocks the first time."""
        if self._samples is None:
            self._samples = self._read()
            self._read = self._drop = None
        return self._samples

    def __del__(self):
        # Unread: its buffer or query objects go back to the pool (GL orders any
        # later reuse after this batch's draw).
        if self._drop is not None:
            self._drop()


_DONE_EMPTY = np.zeros(0, dtype=np.int64)


class _Slot:
    """A 4.3 query batch's own buffer: float32 boxes (lo, hi) at 0, uint counters after."""

    def __init__(self, ctx, progs, cap):
        self.cap = cap
        self.unfenced = False           # shader writes not yet behind a memory barrier
        self.counts_at = _ceil_to(cap * 24, SSBO_ALIGN)
        self.buffer = ctx.buffer(reserve=self.counts_at + 4 * cap)
        # one vertex array per box program (sample counters, flags) on the same buffer
        self.vaos = {kind: ctx.vertex_array(p, [(self.buffer, "3f 3f/i", "in_lo", "in_hi")])
                     for kind, p in progs.items()}


UPLOAD_BLOCK = 1 << 16      # rows per block of the geometry upload (~1.5 MB of float64 vertices)


def _upload_blocks(meshes, centres, vstart, orders, block=UPLOAD_BLOCK):
    """The vertex and index buffers' contents in order, as ``("v", (k, 3) float32)`` and
    ``("i", (j,) uint32)`` blocks of about ``block`` rows: vertices recentred on their
    mesh's centre in float64, then rounded to float32 (the precision rule: small
    offsets from the centre, whatever the data's own dtype); faces in chunk order where
    a mesh is chunked, as absolute indices.  Small meshes go in batches (a few numpy
    calls per batch, not per mesh); a heavy mesh goes block by block."""
    def batch_out(ms):
        vs = [meshes[m][0] for m in ms]
        vn = np.array([len(v) for v in vs], dtype=np.int64)
        v = np.concatenate(vs) - np.repeat(centres[ms], vn, axis=0)
        fs = [meshes[m][1] if orders[m] is None else meshes[m][1][orders[m]] for m in ms]
        fn = np.array([len(f) for f in fs], dtype=np.int64)
        f = np.concatenate(fs).astype(np.int64) + np.repeat(vstart[ms], fn)[:, None]
        return ("v", v.astype(np.float32)), ("i", f.astype(np.uint32).ravel())

    batch, rows = [], 0
    for m, (v, f) in enumerate(meshes):
        if len(v) <= block and len(f) <= block:
            batch.append(m)
            rows += max(len(v), len(f))
            if rows >= block:
                yield from batch_out(batch)
                batch, rows = [], 0
            continue
        if batch:
            yield from batch_out(batch)
            batch, rows = [], 0
        for b in range(0, len(v), block):
            yield "v", (v[b:b + block] - centres[m]).astype(np.float32)
        order = orders[m]
        for b in range(0, len(f), block):
            rows_f = f[b:b + block] if order is None else f[order[b:b + block]]
            yield "i", (rows_f.astype(np.int64) + vstart[m]).astype(np.uint32).ravel()
    if batch:
        yield from batch_out(batch)


class GLRenderer:
    """The scene on the GPU: depth drawing at the display resolution, queries and ID
    truth at ``width x height`` (the query resolution).  See the module doc."""

    def __init__(self, scene, width, height, ctx=None, units=None, display=None, path=None):
        if width < 1 or height < 1:
            raise OccError(f"resolution must be at least 1x1, got {width}x{height}")
        from ..units import whole_objects

        self.width, self.height = int(width), int(height)
        dw, dh = (self.width, self.height) if display is None else (int(display[0]), int(display[1]))
        if dw < self.width or dh < self.height:
            raise OccError(f"display resolution {dw}x{dh} must be at least the query "
                           f"resolution {self.width}x{self.height}")
        self.display = (dw, dh)
        self.reduces = self.display != (self.width, self.height)
        self.own_ctx = ctx is None
        self.ctx = ctx if ctx is not None else create_context()
        self.path = choose_path(self.ctx, path)
        ctx = self.ctx
        self.activate()
        self.counters = dict.fromkeys(COUNTER_KEYS, 0)
        n = len(scene)
        self.n = n
        self.units = units if units is not None else whole_objects(scene)
        self.tri_counts = self.units.count
        # --- geometry, uploaded once -------------------------------------------
        centres = 0.5 * (scene.mesh_bounds[:, 0] + scene.mesh_bounds[:, 1])
        vcount = np.array([len(v) for v, _ in scene.meshes], dtype=np.int64)
        icount = np.array([3 * len(f) for _, f in scene.meshes], dtype=np.int64)
        vstart = np.cumsum(vcount) - vcount
        istart = np.cumsum(icount) - icount
        if vcount.sum() >= 2**32:
            raise OccError("scenes of more than 4 billion vertices are not supported")
        # written block by block into buffers of their final size: no whole-scene or
        # whole-mesh float64 / int64 copy (a few MB of temporaries at any size)
        self.vbo = ctx.buffer(reserve=max(12 * int(vcount.sum()), 12))
        self.ibo = ctx.buffer(reserve=max(4 * int(icount.sum()), 4))
        at = {"v": 0, "i": 0}
        for which, data in _upload_blocks(scene.meshes, centres, vstart, self.units.face_order):
            buf = self.vbo if which == "v" else self.ibo
            buf.write(data, offset=at[which])
            at[which] += data.nbytes
        # per unit: the indirect command (count, instances, first index, base vertex, base instance)
        u = self.units
        self.commands = np.zeros((len(u), 5), dtype=np.uint32)
        if len(u):
            mesh = scene.mesh_of[u.object]
            self.commands[:, 0] = 3 * u.count
            self.commands[:, 1] = 1
            self.commands[:, 2] = istart[mesh] + 3 * u.first
        self.object_offset = np.repeat(np.eye(4)[None], max(n, 1), axis=0)
        if n:
            self.object_offset[:n, :3, 3] = centres[scene.mesh_of]
        self.set_matrices(np.arange(n), scene.matrices)
        # --- programs, vertex arrays, query resources ---------------------------
        if self.path == "4.3":
            self._init_43()
        else:
            self._init_41()
        if self.reduces:
            (dw, dh), (w, h) = self.display, (self.width, self.height)
            if dw % w == 0 and dh % h == 0 and (dw // w) % 2 == 0 and (dh // h) % 2 == 0:
                self.reduce_prog = self._program(S.FULLSCREEN_VERTEX, S.REDUCE_GATHER_FRAGMENT
                                                 % {"rx": dw // w, "ry": dh // h})
                self.reduce_prog["u_texel"].value = (1.0 / dw, 1.0 / dh)
            else:
                self.reduce_prog = self._program(S.FULLSCREEN_VERTEX, S.REDUCE_FRAGMENT)
                self.reduce_prog["u_display"].value = self.display
                self.reduce_prog["u_query"].value = (w, h)
            self.reduce_prog["u_depth"].value = 0
            self.reduce_vao = ctx.vertex_array(self.reduce_prog, [])
        # --- targets ------------------------------------------------------------
        size = (self.width, self.height)
        self.depth_tex = ctx.depth_texture(size)          # what queries test against
        self.query_fbo = ctx.framebuffer(depth_attachment=self.depth_tex)
        self.query_fbo.depth_mask = False                  # query boxes never write depth
        if self.reduces:
            self.display_tex = ctx.depth_texture(self.display)
            self.display_tex.compare_func = ""             # texelFetch / textureGather read depth values
            self.display_tex.repeat_x = self.display_tex.repeat_y = False
            self.display_tex.filter = (ctx.NEAREST, ctx.NEAREST)
            self.fbo = ctx.framebuffer(depth_attachment=self.display_tex)
            self.reduce_fbo = ctx.framebuffer(depth_attachment=self.depth_tex)
        else:
            self.display_tex = self.depth_tex
            self.fbo = ctx.framebuffer(depth_attachment=self.depth_tex)
        self.id_fbos = {}
        self.eye = np.zeros(3)
        self.clip = np.eye(4)
        self.front_face = "ccw"
        self.view_extent = F32_SAFE
        self._vp_set = set()
        self._dirty = None             # query-pixel rectangle drawn at display resolution since
                                       # the last reduction, [x0, y0, x1, y1] inclusive, or None
        self._state = _CONTEXT_STATE.setdefault(self.ctx, {})

    # --- set-up per path -----------------------------------------------------------
    def _program(self, vertex, fragment):
        return self.ctx.program(vertex_shader=S.source(vertex, self.path),
                                fragment_shader=S.source(fragment, self.path))

    def _init_43(self):
        ctx = self.ctx
        self.depth_prog = self._program(S.SCENE_VERTEX_43, S.DEPTH_FRAGMENT)
        self.id_prog = self._program(S.ID_VERTEX_43, S.ID_FRAGMENT)
        self.box_progs = {True: self._program(S.BOX_VERTEX_43, S.BOX_COUNT_FRAGMENT_43),
                          False: self._program(S.BOX_VERTEX_43, S.BOX_FLAG_FRAGMENT_43)}
        # The draw stream, a ring: chunks of [indirect commands | per-instance records]
        # appended frame after frame; when full it is orphaned (draws in flight keep the
        # old storage) and filled again from 0.
        self.stream_size = _pow2(STREAM_ALIGN + (CMD_BYTES + RECORD.itemsize) * max(len(self.units), 1)
                                 + RECORD.itemsize, least=4096)
        self.stream = ctx.buffer(reserve=self.stream_size)
        self.stream_at = 0
        self.depth_vao = ctx.vertex_array(self.depth_prog, [(self.vbo, "3f", "in_pos"),
                                                            (self.stream, "16f 4x/i", "in_mvp")],
                                          index_buffer=self.ibo, index_element_size=4)
        self.id_vao = ctx.vertex_array(self.id_prog, [(self.vbo, "3f", "in_pos"),
                                                      (self.stream, "16f u/i", "in_mvp", "in_id")],
                                       index_buffer=self.ibo, index_element_size=4)
        self.free_slots = {}           # capacity -> [_Slot], batches not pending
        self.slots = []

    def _init_41(self):
        ctx = self.ctx
        self.depth_prog = self._program(S.SCENE_VERTEX_41, S.DEPTH_FRAGMENT)
        self.id_prog = self._program(S.ID_VERTEX_41, S.ID_FRAGMENT)
        self.box_progs = {True: self._program(S.BOX_VERTEX_41, S.DEPTH_FRAGMENT)}
        self.depth_vao = ctx.vertex_array(self.depth_prog, [(self.vbo, "3f", "in_pos")],
                                          index_buffer=self.ibo, index_element_size=4)
        self.id_vao = ctx.vertex_array(self.id_prog, [(self.vbo, "3f", "in_pos")],
                                       index_buffer=self.ibo, index_element_size=4)
        self.box_capacity = 0
        self.box_vbo = None
        self.box_vao = None
        self.free_queries = []         # query objects not held by a pending batch

    def activate(self):
        """Make this renderer's context current: several renderers (each with its own
        context) may be alive at once, and GL calls go to whichever is current."""
        self.ctx.__enter__()

    def _count(self, calls=1, reads=0, draws=0):
        c = self.counters
        c["gl_calls"] += calls
        c["blocking_reads"] += reads
        c["draws"] += draws

    def _use(self, fbo, depth_func, cull):
        """Bind ``fbo`` (it carries its depth mask) and set the depth function and face
        culling, each only when it changes."""
        st, ctx = self._state, self.ctx
        if st.get("fbo") is not fbo:
            fbo.use()
            st["fbo"] = fbo
        if st.get("func") != depth_func:
            ctx.depth_func = depth_func
            st["func"] = depth_func
        if st.get("cull") != cull:
            (ctx.enable if cull else ctx.disable)(ctx.CULL_FACE)
            st["cull"] = cull
        if cull and st.get("front") != self.front_face:
            ctx.front_face = self.front_face
            st["front"] = self.front_face

    # --- per frame -------------------------------------------------------------------
    def set_matrices(self, indices, matrices):
        """Store world matrices ``(k, 4, 4)`` of objects ``indices`` (mesh centre folded in)."""
        m = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        if not hasattr(self, "world"):
            self.world = np.repeat(np.eye(4)[None], max(self.n, 1), axis=0)
            self.model = self.world.copy()
        idx = np.asarray(indices, dtype=np.int64)
        self.model[idx] = m
        self.world[idx] = m @ self.object_offset[idx]

    def begin_frame(self, camera):
        """Start a pass from ``camera``: reset the counters, clear the depth buffer.

        Nothing per object: matrices are made in ``draw`` for what is drawn.
        """
        self.activate()
        self.counters = dict.fromkeys(COUNTER_KEYS, 0)
        self.eye = camera.eye
        self.clip = camera.relative_view_projection()
        # A mirrored camera (negative-determinant view) flips the winding on screen; with
        # OpenGL's clip z pointing away from the eye, an unmirrored camera has det < 0.
        self.front_face = "ccw" if np.linalg.det(self.clip) < 0 else "cw"
        self.view_extent = _view_extent(self.clip)
        self._state.clear()                                # set everything once a frame
        self.ctx.enable(self.ctx.DEPTH_TEST)
        self.fbo.clear(depth=1.0)                          # leaves the bound framebuffer's mask as is
        self._count()
        if self.reduces:                                   # an empty display reduces to an empty query depth
            self.reduce_fbo.clear(depth=1.0)
            self._count()
        self._dirty = None
        self._vp_set = set()                               # box programs given this frame's matrix

    def _mvps(self, units):
        """Camera-relative MVPs of ``units``: float64 math, then ``(k, 4, 4) float32``
        column-major (transposed) as GL reads them."""
        rel = self.world[self.units.object[units]]         # a copy (fancy indexing)
        rel[:, :3, 3] -= self.eye
        return np.ascontiguousarray((self.clip @ rel).transpose(0, 2, 1), dtype=np.float32)

    def draw(self, units, rects=None):
        """Draw units (``(k,) int``) into the depth buffer; returns the triangles drawn.

        rects: ``(k, 4) int`` query-resolution pixel rectangles of the units' boxes,
        rounded outward (``x0, y0, x1, y1`` inclusive, as ``occupancy.project_rects``
        gives), used only when a display resolution is reduced, to reduce only where
        something was drawn; computed here when not given.
        """
        units = np.asarray(units, dtype=np.int64)
        if not len(units):
            return 0
        self._use(self.fbo, "<", False)
        if self.path == "4.3":
            self._draw_43(self.depth_vao, units)
        else:
            self._draw_41(self.depth_prog, self.depth_vao, units)
        if self.reduces:
            self._mark_dirty(self._unit_rects(units) if rects is None else np.asarray(rects))
        return int(self.tri_counts[units].sum())

    def _unit_rects(self, units):
        """Query-pixel rectangles of units' camera-relative boxes, rounded outward."""
        from ..occupancy import project_rects
        boxes = transform_boxes(self.units.local_bounds[units], self.model[self.units.object[units]])
        return project_rects(boxes - self.eye, self.clip, self.width, self.height)[0]

    def _mark_dirty(self, rects):
        box = np.array([*rects[:, :2].min(axis=0), *rects[:, 2:].max(axis=0)])
        if self._dirty is not None:
            box = np.array([*np.minimum(box[:2], self._dirty[:2]), *np.maximum(box[2:], self._dirty[2:])])
        self._dirty = box

    def _draw_43(self, vao, units):
        """One buffer write (commands and records) and one multi-draw."""
        k = len(units)
        need = STREAM_ALIGN + (CMD_BYTES + RECORD.itemsize) * k + RECORD.itemsize
        if self.stream_at + need > self.stream_size:
            self.stream_size = max(self.stream_size, _pow2(need))
            self.stream.orphan(self.stream_size)           # pending draws keep the old storage
            self.stream_at = 0
            self._count()
        at = self.stream_at
        rec_at = _ceil_to(at + CMD_BYTES * k, RECORD.itemsize)
        end = rec_at + RECORD.itemsize * k
        blob = np.zeros(end - at, dtype=np.uint8)
        cmds = self.commands[units]
        cmds[:, 4] = rec_at // RECORD.itemsize + np.arange(k)   # baseInstance: this unit's record
        blob[:CMD_BYTES * k] = cmds.view(np.uint8).ravel()
        rec = np.zeros(k, dtype=RECORD)
        rec["mvp"] = self._mvps(units).reshape(k, 16)
        rec["id"] = self.units.object[units]
        blob[rec_at - at:] = rec.view(np.uint8)
        self.stream.write(blob, offset=at)
        vao.render_indirect(self.stream, count=k, first=at // CMD_BYTES)
        self.stream_at = _ceil_to(end, STREAM_ALIGN)
        self._count(2, draws=1)

    def _draw_41(self, prog, vao, units, ids=False):
        """One uniform write and one draw per unit (no multi-draw, no baseInstance)."""
        mvps = self._mvps(units)
        mvp = prog["u_mvp"]
        objs = self.units.object[units]
        for i, unit in enumerate(units.tolist()):
            mvp.write(mvps[i].tobytes())
            if ids:
                prog["u_id"].value = int(objs[i])
            cmd = self.commands[unit]
            vao.render(vertices=int(cmd[0]), first=int(cmd[2]))
        self._count((3 if ids else 2) * len(units), draws=len(units))

    # --- queries -------------------------------------------------------------------
    def query(self, boxes_rel, counts=True):
        """Samples of each camera-relative box ``(k, 2, 3)`` that pass ``<=`` the depth
        buffer, ``(k,) int64`` (0 = hidden).  One batch: issued, then read back.

        counts: True, the number of samples (what a ``visible_threshold`` > 0 needs);
        False, 1 where any sample passed (4.3: a flag write per fragment instead of an
        atomic add, 8-15x faster on an NVIDIA H200; 4.1: the count clipped to 1).
        """
        return self.query_async(boxes_rel, counts).result()

    def query_async(self, boxes_rel, counts=True):
        """Issue a query batch now; its :class:`PendingQuery` reads the answer later, so
        CPU work can overlap the GPU.  Later draws do not change this batch's answer."""
        # Exact: clipped to a cube around the view frustum, a box keeps every sample it
        # has (its part in the frustum is unchanged), and huge boxes stay in float32.
        boxes_rel = np.clip(np.asarray(boxes_rel, dtype=np.float64), -self.view_extent, self.view_extent)
        k = len(boxes_rel)
        if k == 0:
            return PendingQuery(lambda: _DONE_EMPTY.copy())
        self.counters["query_batches"] += 1
        self._reduce()
        # Front faces only (the side chosen by the camera's handedness): a queried box
        # never contains the eye (that box is visible by rule), so its front faces
        # cover its whole silhouette, each covered pixel centre once.
        self._use(self.query_fbo, "<=", True)
        counts = bool(counts)
        prog = counts if self.path == "4.3" else True      # 4.1 has one box program
        if prog not in self._vp_set:
            self.box_progs[prog]["u_vp"].write(np.ascontiguousarray(self.clip.T, dtype=np.float32).tobytes())
            self._vp_set.add(prog)
            self._count()
        if self.path == "4.3":
            read, drop = self._issue_43(boxes_rel, counts)
        else:
            read, drop = self._issue_41(boxes_rel)
        return PendingQuery(lambda: self._tally(read(), counts), drop)

    def _tally(self, samples, counts):
        if counts:
            self.counters["query_fragments"] += int(samples.sum())
            return samples
        return np.minimum(samples, 1)

    def _issue_43(self, boxes_rel, counts):
        k = len(boxes_rel)
        cap = _pow2(k)
        free = self.free_slots.setdefault(cap, [])
        slot = free.pop() if free else None
        if slot is None:
            slot = _Slot(self.ctx, self.box_progs, cap)
            self.slots.append(slot)
        if slot.unfenced:               # dropped unread: its shader writes must land before ours
            self.ctx.memory_barrier(GL_BUFFER_UPDATE_BARRIER_BIT)
            self._count()
        slot.unfenced = True
        blob = np.zeros(slot.counts_at + 4 * k, dtype=np.uint8)     # counters start at 0
        blob[:24 * k] = boxes_rel.reshape(k, 6).astype(np.float32).view(np.uint8).ravel()
        slot.buffer.write(blob)
        slot.buffer.bind_to_storage_buffer(0, offset=slot.counts_at, size=4 * k)
        slot.vaos[counts].render(vertices=36, instances=k)
        self._count(2, draws=1)

        def read():
            # The barrier here, not after the draw: it makes llvmpipe wait for the draw,
            # and the batch is only waited for when it is read.
            self.ctx.memory_barrier(GL_BUFFER_UPDATE_BARRIER_BIT)
            slot.unfenced = False
            raw = slot.buffer.read(size=4 * k, offset=slot.counts_at)
            self.free_slots[cap].append(slot)
            self._count(2, reads=1)
            return np.frombuffer(raw, dtype=np.uint32).astype(np.int64)
        return read, lambda: self.free_slots[cap].append(slot)

    def _issue_41(self, boxes_rel):
        k = len(boxes_rel)
        self._reserve_boxes(k)
        self.box_vbo.write(box_vertices(boxes_rel).tobytes())
        while len(self.free_queries) < k:
            self.free_queries.append(self.ctx.query(samples=True))
        qs = [self.free_queries.pop() for _ in range(k)]
        vao = self.box_vao
        for i, q in enumerate(qs):             # one query per box; nothing read yet
            with q:
                vao.render(vertices=36, first=36 * i)
        self._count(1 + 3 * k, draws=k)

        def read():
            samples = np.array([q.samples for q in qs], dtype=np.int64)
            self.free_queries.extend(qs)
            self._count(k, reads=k)
            return samples
        return read, lambda: self.free_queries.extend(qs)

    def _reserve_boxes(self, k):
        if k <= self.box_capacity:
            return
        cap = _pow2(k)
        if self.box_vao is not None:
            self.box_vao.release()
            self.box_vbo.release()
        self.box_vbo = self.ctx.buffer(reserve=cap * 36 * 12)
        self.box_vao = self.ctx.vertex_array(self.box_progs[True], [(self.box_vbo, "3f", "in_pos")])
        self.box_capacity = cap

    def _reduce(self):
        """Bring the query-resolution depth up to date with the display-resolution
        depth where something was drawn: each query pixel there gets the farthest
        depth of the display pixels its area overlaps."""
        if self._dirty is None:
            return
        x0, y0, x1, y1 = (int(v) for v in self._dirty)
        # The rectangles cover every query pixel whose area a drawn box overlaps.
        self.reduce_fbo.scissor = (x0, y0, x1 - x0 + 1, y1 - y0 + 1)
        self._use(self.reduce_fbo, "1", False)      # "always": every pixel of the rectangle written
        self.display_tex.use(0)
        self.reduce_vao.render(vertices=3)
        self.reduce_fbo.scissor = None              # bound: moderngl disables the scissor test now
        self._dirty = None
        self._count(1, draws=1)

    def finish(self):
        self.ctx.finish()
        self._count()

    @property
    def device(self):
        """The OpenGL renderer string (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)')."""
        return self.ctx.info.get("GL_RENDERER", "unknown")

    def read_depth(self, display=False):
        """The depth buffer, ``(height, width) float32``, row 0 at the bottom: the one
        queries test against (reduced from the display's), or the display's own."""
        self.activate()
        if display:
            tex, (w, h) = self.display_tex, self.display
        else:
            self._reduce()
            tex, (w, h) = self.depth_tex, (self.width, self.height)
        data = tex.read(alignment=1)
        self._count(1, reads=1)
        return np.frombuffer(data, dtype=np.float32).reshape(h, w)

    # --- ground truth ---------------------------------------------------------
    def object_ids(self, camera, objects=None, display=False):
        """ID buffer from ``camera``: ``(height, width) int64``, -1 = none; at the
        display resolution with ``display=True``.

        objects: the objects to draw (default all of them).
        """
        fbo = self._id_pass(camera, self.display if display else (self.width, self.height), objects)
        return self._read_ids(fbo)

    def ids_and_depth(self, camera, size, objects=None):
        """ID buffer and window depth from ``camera`` at ``size = (w, h)``: ``(h, w)
        int64`` (-1 = none) and ``(h, w) float32`` in [0, 1] (1 = nothing drawn), row 0
        at the bottom.  The envelope pass (:mod:`core.envelope`) erodes these."""
        fbo = self._id_pass(camera, size, objects)
        ids = self._read_ids(fbo)
        raw = fbo.read(components=1, attachment=-1, dtype="f4", alignment=1)
        self._count(1, reads=1)
        return ids, np.frombuffer(raw, dtype=np.float32).reshape(ids.shape)

    def _id_pass(self, camera, size, objects):
        """Draw ``objects`` (default all) with their ids from ``camera`` into an
        ``size`` target of their own; returns its framebuffer."""
        self.begin_frame(camera)
        w, h = (int(size[0]), int(size[1]))
        fbo = self.id_fbos.get((w, h))
        if fbo is None:
            fbo = self.ctx.framebuffer(color_attachments=[self.ctx.texture((w, h), 1, dtype="u4")],
                                       depth_attachment=self.ctx.depth_renderbuffer((w, h)))
            self.id_fbos[(w, h)] = fbo
        fbo.clear(depth=1.0)
        self._state.clear()                                # the clear re-bound a framebuffer
        self._use(fbo, "<", False)
        units = np.arange(len(self.units))
        if objects is not None:
            keep = np.zeros(self.n, dtype=bool)
            keep[np.asarray(objects, dtype=np.int64)] = True
            units = units[keep[self.units.object]]
        if len(units):
            if self.path == "4.3":
                self._draw_43(self.id_vao, units)
            else:
                self._draw_41(self.id_prog, self.id_vao, units, ids=True)
        return fbo

    def _read_ids(self, fbo):
        w, h = fbo.size
        raw = fbo.read(components=1, dtype="u4", alignment=1)
        self._count(1, reads=1)
        ids = np.frombuffer(raw, dtype=np.uint32).reshape(h, w)
        return ids.astype(np.int64) - 1

    def visible_truth(self, camera, display=False):
        """Exact visible set at the query (or display) resolution: ``(n,) bool``, an
        object covers a pixel centre."""
        ids = self.object_ids(camera, display=display)
        out = np.zeros(self.n, dtype=bool)
        out[ids[ids >= 0]] = True
        return out

    def release(self):
        """Free the GPU objects (and the context when this renderer created it)."""
        self.activate()
        if self.own_ctx:
            self.ctx.release()
            return
        gpu = getattr(self, "gpu_cull", None)          # the gpu strategy's buffers (core/gl/gpucull.py)
        if gpu is not None:
            gpu.release()
        objs = [self.depth_vao, self.id_vao, self.vbo, self.ibo, self.depth_prog, self.id_prog,
                *self.box_progs.values(), self.fbo, self.query_fbo, self.depth_tex]
        if self.path == "4.3":
            objs += [self.stream]
            for s in self.slots:
                objs += [*s.vaos.values(), s.buffer]
        else:
            objs += [self.box_vao, self.box_vbo]           # moderngl queries have no release
        if self.reduces:
            objs += [self.reduce_vao, self.reduce_prog, self.reduce_fbo, self.display_tex]
        for fbo in self.id_fbos.values():
            objs += [fbo, *fbo.color_attachments, fbo.depth_attachment]
        # Unbind our framebuffer first: moderngl re-binds "the current one" after
        # creating the next, and a deleted name there is GL_INVALID_OPERATION.
        self.ctx.detect_framebuffer(0).use()
        for o in objs:
            if o is not None:
                o.release()
