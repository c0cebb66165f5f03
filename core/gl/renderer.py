"""Depth rendering, one-draw occlusion queries and object-ID truth on moderngl.

Meshes are uploaded once: one vertex buffer (each mesh recentred on its own box
centre, so float32 keeps its precision), one index buffer of absolute indices,
and per draw unit an index range.  Matrices are made camera-relative in float64
-- ``P @ R @ (M @ T(centre) - T(eye))`` -- and only then rounded to float32, so a
scene 1e6 units from the origin renders as well as one at it; this is done in
``draw`` for the units drawn, never for the whole scene per frame.

Two GL paths (see :mod:`core.gl.context`; ``OCC_GL=4.1`` forces the second), two
implementations of the :class:`Renderer` interface on one base class
(:class:`BaseRenderer`, what both share: geometry, targets, reduction, truth):

- 4.3 (:class:`core.gl.renderer_43.Renderer43`): a ``draw`` is one
  ``glMultiDrawElementsIndirect`` whose commands and per-draw MVPs go up in one buffer
  write (a ring of draw data, picked by baseInstance).  A query batch is ONE instanced
  draw of all its boxes (corners expanded in the vertex shader), early depth test
  ``<=``, no depth or colour write; every passing fragment adds one to its box's
  counter in a storage buffer (or, with ``counts=False``, sets its flag), read back
  once per batch; each pending batch owns its buffer.
- 4.1 (macOS, :class:`core.gl.renderer_41.Renderer41`): one draw per unit with a
  uniform MVP, one occlusion query object per box, one blocking read per box.

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

Hooks for passes built on the renderer (:mod:`core.gl.gpucull`): :meth:`~BaseRenderer.count_gl`,
:meth:`~BaseRenderer.use_draw_target`, :meth:`~BaseRenderer.use_query_target`,
:meth:`~BaseRenderer.mark_drawn`, :meth:`~BaseRenderer.reduce`, and
:meth:`~BaseRenderer.attachment` (GPU objects made once per renderer and released with it).
"""

import weakref
from typing import Callable, Protocol, TypeVar, runtime_checkable

import numpy as np

from ..bounds import transform_boxes
from ..errors import OccError
from ..occupancy import project_rects
from ..settings import check_resolution
from ..units import whole_objects
from . import gpuenvelope, shaders
from .context import choose_path, create_context
from .layout import BOX_TRIANGLES  # noqa: F401  (re-exported: the renderer's box triangles)
from .upload import box_vertices, upload_blocks

# GL state this package set last, per context: renderers sharing a context share it.
_CONTEXT_STATE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
F32_SAFE = 1e30                         # far inside float32's range, after a projection too
NDC_CORNERS = np.array([(x, y, z, 1.0) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)])
COUNTER_KEYS = ("gl_calls", "blocking_reads", "query_fragments", "draws", "query_batches")
T = TypeVar("T")

__all__ = ["BaseRenderer", "PendingQuery", "Renderer", "box_vertices"]


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


def ceil_to(x, m):
    return -(-x // m) * m


def pow2(x, least=64):
    return max(least, 1 << int(np.ceil(np.log2(max(x, 1)))))



def release_context(ctx) -> None:
    """Release ``ctx`` and everything made on it, with the renderers' state kept for it
    (that state holds a framebuffer that holds the context: the weak key alone would
    keep every context this process made)."""
    _CONTEXT_STATE.pop(ctx, None)
    ctx.release()

class PendingQuery:
    """A query batch issued and not read yet; :meth:`result` reads it back once.

    Draws issued in between do not change its answer: the batch owns its result
    buffer (4.3) or query objects (4.1) until it is read (or dropped unread).
    """

    __slots__ = ("_read", "_drop", "_samples")

    def __init__(self, read, drop=None):
        self._read, self._drop, self._samples = read, drop, None

    def result(self) -> np.ndarray:
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


@runtime_checkable
class Renderer(Protocol):
    """What the engine, the strategies and the truth passes use of a renderer (both
    GL paths implement it; see the module doc)."""

    path: str                       # "4.3" or "4.1"
    width: int                      # the query resolution
    height: int
    display: tuple                  # the display resolution (w, h), >= the query resolution
    reduces: bool                   # display != query resolution
    n: int                          # objects
    units: object                   # core.units draw units
    tri_counts: np.ndarray          # (units,) triangles of each unit
    counters: dict                  # module doc; reset by begin_frame
    own_ctx: bool                   # release() releases the context too
    eye: np.ndarray                 # (3,) float64, this frame's
    clip: np.ndarray                # (4, 4) float64 camera-relative view-projection, this frame's
    world: np.ndarray               # (n, 4, 4) float64 world matrices, mesh centre folded in
    model: np.ndarray               # (n, 4, 4) float64 world matrices as given

    def activate(self) -> None: ...
    def set_matrices(self, indices, matrices) -> None: ...
    def begin_frame(self, camera) -> None: ...
    def draw(self, units, rects=None) -> int: ...
    def query(self, boxes_rel, counts: bool = True) -> np.ndarray: ...
    def query_async(self, boxes_rel, counts: bool = True) -> PendingQuery: ...
    def finish(self) -> None: ...
    def read_depth(self, display: bool = False) -> np.ndarray: ...
    def object_ids(self, camera, objects=None, display: bool = False) -> np.ndarray: ...
    def envelope_depth(self, camera, size, objects=None): ...
    def read_texture_depth(self, tex) -> np.ndarray: ...
    def gpu_envelope(self): ...
    def visible_truth(self, camera, display: bool = False) -> np.ndarray: ...
    def release(self) -> None: ...


class BaseRenderer:
    """The scene on the GPU: depth drawing at the display resolution, queries and ID
    truth at ``width x height`` (the query resolution).  What both GL paths share;
    a subclass per path draws units, issues query batches and owns its programs
    (the methods marked "per path").  See the module doc."""

    path = ""                       # per path: "4.3" or "4.1"
    # per path, made by the subclass: the box programs by _box_program_key, the scene's VAOs
    box_progs: dict
    depth_vao: object
    id_vao: object

    def __init__(self, scene, width: int, height: int, ctx=None, units=None, display=None):
        (self.width, self.height), self.display = check_resolution((width, height), display)
        self.reduces = self.display != (self.width, self.height)
        self.own_ctx = ctx is None
        self.ctx = ctx if ctx is not None else create_context()
        choose_path(self.ctx, self.path)              # an error where the context lacks the path
        self.activate()
        self.counters = dict.fromkeys(COUNTER_KEYS, 0)
        self._upload_geometry(scene, units)
        # the scene's vertex shader serves both paths (core/gl/glsl/scene.vert.glsl)
        self.depth_prog = self.program("scene.vert.glsl", "depth.frag.glsl")
        self.id_prog = self.program("scene.vert.glsl", "id.frag.glsl", WITH_ID=1)
        self._init_path()
        if self.reduces:
            self._init_reduction()
        self._init_targets()
        self._init_frame_state()

    # --- set-up ------------------------------------------------------------------------
    def _upload_geometry(self, scene, units):
        """The vertex and index buffers (written block by block into buffers of their
        final size: no whole-scene or whole-mesh float64 / int64 copy), each unit's
        indirect command, and the objects' matrices."""
        n = len(scene)
        self.n = n
        self.units = units if units is not None else whole_objects(scene)
        self.tri_counts = self.units.count
        centres = 0.5 * (scene.mesh_bounds[:, 0] + scene.mesh_bounds[:, 1])
        vcount = np.array([len(v) for v, _ in scene.meshes], dtype=np.int64)
        icount = np.array([3 * len(f) for _, f in scene.meshes], dtype=np.int64)
        vstart = np.cumsum(vcount) - vcount
        istart = np.cumsum(icount) - icount
        if vcount.sum() >= 2**32:
            raise OccError("scenes of more than 4 billion vertices are not supported")
        self.vbo = self.ctx.buffer(reserve=max(12 * int(vcount.sum()), 12))
        self.ibo = self.ctx.buffer(reserve=max(4 * int(icount.sum()), 4))
        at = {"v": 0, "i": 0}
        for which, data in upload_blocks(scene.meshes, centres, vstart, self.units.face_order):
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
        self.world = np.repeat(np.eye(4)[None], max(n, 1), axis=0)
        self.model = self.world.copy()
        self.set_matrices(np.arange(n), scene.matrices)

    def _init_path(self):
        """Per path: its own programs, vertex arrays and query resources."""
        raise NotImplementedError

    def _init_reduction(self):
        """The display -> query depth reduction's program: one textureGather per 2 x 2
        display pixels where the display is an even multiple of the query resolution,
        else the general loop."""
        (dw, dh), (w, h) = self.display, (self.width, self.height)
        if dw % w == 0 and dh % h == 0 and (dw // w) % 2 == 0 and (dh // h) % 2 == 0:
            self.reduce_prog = self.program("fullscreen.vert.glsl", "reduce_gather.frag.glsl",
                                            RX=dw // w, RY=dh // h)
            self.reduce_prog["u_texel"].value = (1.0 / dw, 1.0 / dh)
        else:
            self.reduce_prog = self.program("fullscreen.vert.glsl", "reduce.frag.glsl")
            self.reduce_prog["u_display"].value = self.display
            self.reduce_prog["u_query"].value = (w, h)
        self.reduce_prog["u_depth"].value = 0
        self.reduce_vao = self.ctx.vertex_array(self.reduce_prog, [])

    def _init_targets(self):
        """The query-resolution depth (what queries test against) and, with a larger
        display, the display's depth and the reduction's target."""
        ctx = self.ctx
        self.depth_tex = ctx.depth_texture((self.width, self.height))
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
        self.depth_fbos = {}          # (w, h) -> a framebuffer with a depth texture only (the envelope's)

    def _init_frame_state(self):
        self.eye = np.zeros(3)
        self.clip = np.eye(4)
        self.front_face = "ccw"
        self.view_extent = F32_SAFE
        self._vp_set = set()
        self._dirty = None             # query-pixel rectangle drawn at display resolution since
                                       # the last reduction, [x0, y0, x1, y1] inclusive, or None
        self._state = _CONTEXT_STATE.setdefault(self.ctx, {})
        self._attachments = {}

    def program(self, vertex: str, fragment: str, **defines):
        """A program of ``core/gl/glsl`` files for this path; ``defines`` go before each."""
        return self.ctx.program(vertex_shader=shaders.source(vertex, self.path, defines),
                                fragment_shader=shaders.source(fragment, self.path, defines))

    # --- hooks for passes built on the renderer (core.gl.gpucull) -----------------------
    def activate(self) -> None:
        """Make this renderer's context current: several renderers (each with its own
        context) may be alive at once, and GL calls go to whichever is current."""
        self.ctx.__enter__()

    def count_gl(self, calls: int = 1, reads: int = 0, draws: int = 0, batches: int = 0) -> None:
        """Add GL work done on this renderer's behalf to ``counters`` (module doc)."""
        c = self.counters
        c["gl_calls"] += calls
        c["blocking_reads"] += reads
        c["draws"] += draws
        c["query_batches"] += batches

    def use_target(self, fbo, depth_func: str, cull: bool) -> None:
        """Bind ``fbo`` (it carries its depth mask) and set the depth function and face
        culling (front faces: this frame's winding), each only when it changes."""
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

    def use_draw_target(self) -> None:
        """Geometry: the display-resolution depth, test ``<``, both faces."""
        self.use_target(self.fbo, "<", False)

    def use_query_target(self) -> None:
        """Query boxes: the query-resolution depth (no depth write), test ``<=``, front faces."""
        self.use_target(self.query_fbo, "<=", True)

    def mark_drawn(self, rects: np.ndarray | None = None) -> None:
        """Something was drawn at the display resolution inside ``(k, 4) int`` query-pixel
        rectangles (``x0, y0, x1, y1`` inclusive), or anywhere (None: the whole target):
        the next :meth:`reduce` brings the query depth up to date there."""
        if rects is None:
            self._dirty = np.array([0, 0, self.width - 1, self.height - 1])
            return
        box = np.array([*rects[:, :2].min(axis=0), *rects[:, 2:].max(axis=0)])
        if self._dirty is not None:
            box = np.array([*np.minimum(box[:2], self._dirty[:2]), *np.maximum(box[2:], self._dirty[2:])])
        self._dirty = box

    def reduce(self) -> None:
        """Bring the query-resolution depth up to date with the display-resolution
        depth where something was drawn: each query pixel there gets the farthest
        depth of the display pixels its area overlaps."""
        if self._dirty is None:
            return
        x0, y0, x1, y1 = (int(v) for v in self._dirty)
        # The rectangles cover every query pixel whose area a drawn box overlaps.
        self.reduce_fbo.scissor = (x0, y0, x1 - x0 + 1, y1 - y0 + 1)
        self.use_target(self.reduce_fbo, "1", False)      # "always": every pixel of the rectangle written
        self.display_tex.use(0)
        self.reduce_vao.render(vertices=3)
        self.reduce_fbo.scissor = None              # bound: moderngl disables the scissor test now
        self._dirty = None
        self.count_gl(1, draws=1)

    def attachment(self, key: str, factory: Callable[["BaseRenderer"], T]) -> T:
        """The object attached to this renderer under ``key``, made by ``factory(self)``
        the first time (nothing is kept where it raises); attachments hold GPU objects
        of this renderer's context and are released with it (:meth:`release`)."""
        got = self._attachments.get(key)
        if got is None:
            got = self._attachments[key] = factory(self)
        return got

    # --- per frame ---------------------------------------------------------------------
    def set_matrices(self, indices, matrices) -> None:
        """Store world matrices ``(k, 4, 4)`` of objects ``indices`` (mesh centre folded in)."""
        m = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        idx = np.asarray(indices, dtype=np.int64)
        self.model[idx] = m
        self.world[idx] = m @ self.object_offset[idx]

    def begin_frame(self, camera) -> None:
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
        self.count_gl()
        if self.reduces:                                   # an empty display reduces to an empty query depth
            self.reduce_fbo.clear(depth=1.0)
            self.count_gl()
        self._dirty = None
        self._vp_set = set()                               # box programs given this frame's matrix

    def mvps(self, units: np.ndarray) -> np.ndarray:
        """Camera-relative MVPs of ``units``: float64 math, then ``(k, 4, 4) float32``
        column-major (transposed) as GL reads them."""
        rel = self.world[self.units.object[units]]         # a copy (fancy indexing)
        rel[:, :3, 3] -= self.eye
        return np.ascontiguousarray((self.clip @ rel).transpose(0, 2, 1), dtype=np.float32)

    def draw(self, units, rects=None) -> int:
        """Draw units (``(k,) int``) into the depth buffer; returns the triangles drawn.

        rects: ``(k, 4) int`` query-resolution pixel rectangles of the units' boxes,
        rounded outward (``x0, y0, x1, y1`` inclusive, as ``occupancy.project_rects``
        gives), used only when a display resolution is reduced, to reduce only where
        something was drawn; computed here when not given.
        """
        units = np.asarray(units, dtype=np.int64)
        if not len(units):
            return 0
        self.use_draw_target()
        self._draw_units(units, ids=False)
        if self.reduces:
            self.mark_drawn(self._unit_rects(units) if rects is None else np.asarray(rects))
        return int(self.tri_counts[units].sum())

    def _draw_units(self, units, ids):
        """Per path: draw ``units`` into the bound target, with their ids (``ids``) or
        depth only."""
        raise NotImplementedError

    def _unit_rects(self, units):
        """Query-pixel rectangles of units' camera-relative boxes, rounded outward."""
        boxes = transform_boxes(self.units.local_bounds[units], self.model[self.units.object[units]])
        return project_rects(boxes - self.eye, self.clip, self.width, self.height)[0]

    # --- queries -------------------------------------------------------------------
    def query(self, boxes_rel, counts: bool = True) -> np.ndarray:
        """Samples of each camera-relative box ``(k, 2, 3)`` that pass ``<=`` the depth
        buffer, ``(k,) int64`` (0 = hidden).  One batch: issued, then read back.

        counts: True, the number of samples (what a ``visible_threshold`` > 0 needs);
        False, 1 where any sample passed (4.3: a flag write per fragment instead of an
        atomic add, 8-15x faster on an NVIDIA H200; 4.1: the count clipped to 1).
        """
        return self.query_async(boxes_rel, counts).result()

    def query_async(self, boxes_rel, counts: bool = True) -> PendingQuery:
        """Issue a query batch now; its :class:`PendingQuery` reads the answer later, so
        CPU work can overlap the GPU.  Later draws do not change this batch's answer."""
        # Exact: clipped to a cube around the view frustum, a box keeps every sample it
        # has (its part in the frustum is unchanged), and huge boxes stay in float32.
        boxes_rel = np.clip(np.asarray(boxes_rel, dtype=np.float64), -self.view_extent, self.view_extent)
        k = len(boxes_rel)
        if k == 0:
            return PendingQuery(lambda: _DONE_EMPTY.copy())
        self.counters["query_batches"] += 1
        self.reduce()
        # Front faces only (the side chosen by the camera's handedness): a queried box
        # never contains the eye (that box is visible by rule), so its front faces
        # cover its whole silhouette, each covered pixel centre once.
        self.use_query_target()
        counts = bool(counts)
        prog = self._box_program_key(counts)
        if prog not in self._vp_set:
            self.box_progs[prog]["u_vp"].write(np.ascontiguousarray(self.clip.T, dtype=np.float32).tobytes())
            self._vp_set.add(prog)
            self.count_gl()
        read, drop = self._issue(boxes_rel, counts)
        return PendingQuery(lambda: self._tally(read(), counts), drop)

    def _box_program_key(self, counts):
        """Per path: the key in ``box_progs`` of the program a batch draws with."""
        raise NotImplementedError

    def _issue(self, boxes_rel, counts):
        """Per path: issue a batch; ``(read, drop)``: read its samples ``(k,) int64``
        once, or give its resources back unread."""
        raise NotImplementedError

    def _tally(self, samples, counts):
        if counts:
            self.counters["query_fragments"] += int(samples.sum())
            return samples
        return np.minimum(samples, 1)

    def finish(self) -> None:
        self.ctx.finish()
        self.count_gl()

    @property
    def device(self) -> str:
        """The OpenGL renderer string (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)')."""
        return self.ctx.info.get("GL_RENDERER", "unknown")

    def read_depth(self, display: bool = False) -> np.ndarray:
        """The depth buffer, ``(height, width) float32``, row 0 at the bottom: the one
        queries test against (reduced from the display's), or the display's own."""
        self.activate()
        if display:
            tex, (w, h) = self.display_tex, self.display
        else:
            self.reduce()
            tex, (w, h) = self.depth_tex, (self.width, self.height)
        data = tex.read(alignment=1)
        self.count_gl(1, reads=1)
        return np.frombuffer(data, dtype=np.float32).reshape(h, w)

    # --- ground truth ---------------------------------------------------------
    def object_ids(self, camera, objects=None, display: bool = False) -> np.ndarray:
        """ID buffer from ``camera``: ``(height, width) int64``, -1 = none; at the
        display resolution with ``display=True``.

        objects: the objects to draw (default all of them).
        """
        fbo = self._id_pass(camera, self.display if display else (self.width, self.height), objects)
        return self._read_ids(fbo)

    def envelope_depth(self, camera, size, objects=None):
        """The depth of ``objects`` (default all) from ``camera`` at ``size = (w, h)``,
        drawn into a depth texture of its own (one per size, kept): the envelope pass's
        image (:mod:`core.envelope`), a pixel covered where its depth is below 1 (the
        clear).  Returns the texture (``compare_func`` off: shaders fetch depths)."""
        self.begin_frame(camera)
        w, h = (int(size[0]), int(size[1]))
        fbo = self.depth_fbos.get((w, h))
        if fbo is None:
            tex = self.ctx.depth_texture((w, h))
            tex.compare_func = ""
            fbo = self.depth_fbos[(w, h)] = self.ctx.framebuffer(depth_attachment=tex)
        self._draw_into(fbo, objects, ids=False)
        return fbo.depth_attachment

    def gpu_envelope(self):
        """The envelope's image work on this renderer's GPU
        (:class:`~core.gl.gpuenvelope.GpuEnvelope`), or None (the 4.1 path, ``OCC_ENVELOPE``,
        a software rasteriser, or shaders the driver refuses): then
        :func:`core.envelope.extended_depth` does it in numpy."""
        return gpuenvelope.for_renderer(self)

    def read_texture_depth(self, tex) -> np.ndarray:
        """A depth texture's window depths, ``(h, w) float32`` in [0, 1], row 0 at the bottom."""
        w, h = tex.size
        data = tex.read(alignment=1)
        self.count_gl(1, reads=1)
        return np.frombuffer(data, dtype=np.float32).reshape(h, w)

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
        self._draw_into(fbo, objects, ids=True)
        return fbo

    def _draw_into(self, fbo, objects, ids):
        """Clear ``fbo`` and draw ``objects`` (default all) into it, test ``<``, both faces."""
        fbo.clear(depth=1.0)
        self._state.clear()                                # the clear re-bound a framebuffer
        self.use_target(fbo, "<", False)
        units = np.arange(len(self.units))
        if objects is not None:
            keep = np.zeros(self.n, dtype=bool)
            keep[np.asarray(objects, dtype=np.int64)] = True
            units = units[keep[self.units.object]]
        if len(units):
            self._draw_units(units, ids=ids)

    def _read_ids(self, fbo):
        w, h = fbo.size
        raw = fbo.read(components=1, dtype="u4", alignment=1)
        self.count_gl(1, reads=1)
        ids = np.frombuffer(raw, dtype=np.uint32).reshape(h, w)
        return ids.astype(np.int64) - 1

    def visible_truth(self, camera, display: bool = False) -> np.ndarray:
        """Exact visible set at the query (or display) resolution: ``(n,) bool``, an
        object covers a pixel centre."""
        ids = self.object_ids(camera, display=display)
        out = np.zeros(self.n, dtype=bool)
        out[ids[ids >= 0]] = True
        return out

    def release(self) -> None:
        """Free the GPU objects, attachments first (and the context when this renderer
        created it: that frees them all)."""
        self.activate()
        if self.own_ctx:
            release_context(self.ctx)
            return
        for a in reversed(list(self._attachments.values())):
            a.release()
        self._attachments.clear()
        objs = [self.depth_vao, self.id_vao, self.vbo, self.ibo, self.depth_prog, self.id_prog,
                *self.box_progs.values(), self.fbo, self.query_fbo, self.depth_tex, *self._path_objects()]
        if self.reduces:
            objs += [self.reduce_vao, self.reduce_prog, self.reduce_fbo, self.display_tex]
        for fbo in [*self.id_fbos.values(), *self.depth_fbos.values()]:
            objs += [fbo, *fbo.color_attachments, fbo.depth_attachment]
        # Unbind our framebuffer first: moderngl re-binds "the current one" after
        # creating the next, and a deleted name there is GL_INVALID_OPERATION.
        self.ctx.detect_framebuffer(0).use()
        self._state.clear()            # the context outlives this renderer: nothing of ours is bound
        for o in objs:
            if o is not None:
                o.release()

    def _path_objects(self):
        """Per path: its own GL objects to release."""
        raise NotImplementedError
