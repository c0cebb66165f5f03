"""Depth rendering, batched occlusion queries and object-ID truth on moderngl/EGL.

Meshes are uploaded once: one vertex buffer (each mesh recentred on its own box
centre, so float32 keeps its precision), one index buffer of absolute indices,
and per object an index range.  Every frame the per-object matrices are made
camera-relative in float64 -- ``P @ R @ (M @ T(centre) - T(eye))`` -- and only
then rounded to float32, so a scene 1e6 units from the origin renders as well as
one at it.  All visible objects of a batch go out in one
``glMultiDrawElementsIndirect``; all boxes of a query batch come from one
vertex buffer, and every query of a batch is issued before any result is read
(moderngl's ``Query.samples`` blocks).

Depth test: ``<`` for geometry, ``<=`` for query boxes -- ties count as visible.
"""

import os
import sys

import numpy as np

from ..bounds import corners
from ..errors import OccError

MIN_GL_VERSION = 430            # glMultiDrawElementsIndirect and baseInstance
EGL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"

# 12 triangles of a box, counter-clockwise seen from outside, as indices into
# bounds.corners' bit order (x=1, y=2, z=4).
BOX_TRIANGLES = np.array([
    0, 2, 1, 1, 2, 3,   4, 5, 6, 5, 7, 6,   0, 1, 4, 1, 5, 4,
    2, 6, 3, 3, 6, 7,   0, 4, 2, 2, 4, 6,   1, 3, 5, 3, 7, 5,
], dtype=np.intp)

_VERTEX = """
#version 430
in vec3 in_pos;
in mat4 in_mvp;
in uint in_id;
flat out uint v_id;
void main() {
    gl_Position = in_mvp * vec4(in_pos, 1.0);
    v_id = in_id + 1u;
}
"""
_DEPTH_FRAGMENT = """
#version 430
void main() {}
"""
_ID_FRAGMENT = """
#version 430
flat in uint v_id;
out uint f_id;
void main() { f_id = v_id; }
"""
_BOX_VERTEX = """
#version 430
in vec3 in_pos;
uniform mat4 u_vp;
void main() { gl_Position = u_vp * vec4(in_pos, 1.0); }
"""


def create_context():
    """A standalone OpenGL >= 4.3 context; EGL on Linux (headless, no display)."""
    try:
        import moderngl
    except ImportError:
        raise OccError("the GPU backend needs moderngl: pip install moderngl") from None
    kwargs = {"backend": "egl"} if sys.platform.startswith("linux") else {}
    if os.environ.get("OCC_LIBEGL"):          # a specific libEGL (or, in tests, a missing one)
        kwargs["libegl"] = os.environ["OCC_LIBEGL"]
    try:
        ctx = moderngl.create_context(standalone=True, require=MIN_GL_VERSION, **kwargs)
    except Exception as e:  # moderngl/glcontext raise plain Exceptions for missing libraries
        hint = (f"install Mesa's EGL: apt-get install {EGL_PACKAGES}"
                if sys.platform.startswith("linux") else "update the graphics driver")
        raise OccError(f"no OpenGL {MIN_GL_VERSION // 100}.{MIN_GL_VERSION % 100 // 10} context "
                       f"could be created ({e}); {hint}") from None
    return ctx


def box_vertices(boxes):
    """Triangle-list vertices of boxes: ``(k, 2, 3)`` -> ``(k * 36, 3) float32``."""
    return corners(boxes)[:, BOX_TRIANGLES].reshape(-1, 3).astype(np.float32)


class GLRenderer:
    """The scene on the GPU at ``width x height``: depth drawing, queries, ID truth."""

    def __init__(self, scene, width, height, ctx=None, units=None):
        if width < 1 or height < 1:
            raise OccError(f"resolution must be at least 1x1, got {width}x{height}")
        from ..units import whole_objects

        self.own_ctx = ctx is None
        self.ctx = ctx if ctx is not None else create_context()
        self.width, self.height = int(width), int(height)
        ctx = self.ctx
        self.activate()
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
        verts = [(v - c).astype(np.float32) for (v, _), c in zip(scene.meshes, centres, strict=True)]
        # faces in chunk order where a mesh is chunked, as absolute uint32 indices
        idx = [((f if order is None else f[order]) + s).astype(np.uint32).ravel()
               for (_, f), s, order in zip(scene.meshes, vstart, self.units.face_order, strict=True)]
        vdata = np.concatenate(verts) if verts else np.zeros((0, 3), np.float32)
        idata = np.concatenate(idx) if idx else np.zeros(0, np.uint32)
        self.vbo = ctx.buffer(vdata.tobytes() or b"\0" * 12)
        self.ibo = ctx.buffer(idata.tobytes() or b"\0" * 4)
        # per unit: the indirect command (count, instances, first index, base vertex, base instance)
        u = self.units
        self.commands = np.zeros((max(len(u), 1), 5), dtype=np.uint32)
        if len(u):
            mesh = scene.mesh_of[u.object]
            self.commands[:len(u), 0] = 3 * u.count
            self.commands[:len(u), 1] = 1
            self.commands[:len(u), 2] = istart[mesh] + 3 * u.first
            self.commands[:len(u), 4] = u.object
        self.cmd_buffer = ctx.buffer(reserve=self.commands.nbytes)
        self.object_offset = np.repeat(np.eye(4)[None], max(n, 1), axis=0)
        if n:
            self.object_offset[:n, :3, 3] = centres[scene.mesh_of]
        self.set_matrices(np.arange(n), scene.matrices)
        self.mvp_buffer = ctx.buffer(reserve=max(n, 1) * 64)
        self.id_buffer = ctx.buffer(np.arange(max(n, 1), dtype=np.uint32).tobytes())
        # --- programs and vertex arrays ---------------------------------------
        self.depth_prog = ctx.program(vertex_shader=_VERTEX, fragment_shader=_DEPTH_FRAGMENT)
        self.id_prog = ctx.program(vertex_shader=_VERTEX, fragment_shader=_ID_FRAGMENT)
        self.box_prog = ctx.program(vertex_shader=_BOX_VERTEX, fragment_shader=_DEPTH_FRAGMENT)
        self.depth_vao = self._scene_vao(self.depth_prog, with_id=False)
        self.id_vao = self._scene_vao(self.id_prog, with_id=True)
        self.box_capacity = 0
        self.box_vbo = None
        self.box_vao = None
        self.queries = []
        # --- targets ------------------------------------------------------------
        size = (self.width, self.height)
        self.depth_tex = ctx.depth_texture(size)
        self.fbo = ctx.framebuffer(depth_attachment=self.depth_tex)
        self.id_fbo = ctx.framebuffer(color_attachments=[ctx.texture(size, 1, dtype="u4")],
                                      depth_attachment=ctx.depth_renderbuffer(size))
        self.eye = np.zeros(3)
        self.clip = np.eye(4)

    def _scene_vao(self, prog, with_id):
        content = [(self.vbo, "3f", "in_pos"), (self.mvp_buffer, "16f/i", "in_mvp")]
        if with_id:
            content.append((self.id_buffer, "u/i", "in_id"))
        return self.ctx.vertex_array(prog, content, index_buffer=self.ibo, index_element_size=4)

    def activate(self):
        """Make this renderer's context current: several renderers (each with its own
        context) may be alive at once, and GL calls go to whichever is current."""
        self.ctx.__enter__()

    # --- per frame -----------------------------------------------------------
    def set_matrices(self, indices, matrices):
        """Store world matrices ``(k, 4, 4)`` of objects ``indices`` (mesh centre folded in)."""
        m = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        self.world = getattr(self, "world", np.repeat(np.eye(4)[None], max(self.n, 1), axis=0))
        idx = np.asarray(indices, dtype=np.int64)
        self.world[idx] = m @ self.object_offset[idx]

    def begin_frame(self, camera):
        """Upload camera-relative matrices for ``camera`` and clear the depth buffer."""
        self.activate()
        self.eye = camera.eye
        self.clip = camera.relative_view_projection()
        rel = self.world.copy()
        rel[:, :3, 3] -= self.eye
        mvp = self.clip @ rel                                 # float64, camera-relative
        self.mvp_buffer.write(np.ascontiguousarray(mvp.transpose(0, 2, 1), dtype=np.float32).tobytes())
        self.fbo.use()
        self.fbo.depth_mask = True
        self.fbo.clear(depth=1.0)
        self.ctx.enable(self.ctx.DEPTH_TEST)
        self.ctx.disable(self.ctx.CULL_FACE)
        self.box_prog["u_vp"].write(np.ascontiguousarray(self.clip.T, dtype=np.float32).tobytes())

    def draw(self, units):
        """Draw units (``(k,) int``) into the depth buffer with one indirect multi-draw.

        Returns the number of triangles drawn.
        """
        units = np.asarray(units, dtype=np.int64)
        if not len(units):
            return 0
        self.fbo.use()
        self.fbo.depth_mask = True
        self.ctx.depth_func = "<"
        self.cmd_buffer.orphan()
        self.cmd_buffer.write(self.commands[units].tobytes())
        self.depth_vao.render_indirect(self.cmd_buffer, count=len(units))
        return int(self.tri_counts[units].sum())

    def query(self, boxes_rel):
        """Samples of each camera-relative box ``(k, 2, 3)`` that pass ``<=`` the depth buffer.

        All k queries are issued before the first result is read.
        """
        boxes_rel = np.asarray(boxes_rel, dtype=np.float64)
        k = len(boxes_rel)
        if k == 0:
            return np.zeros(0, dtype=np.int64)
        self._reserve_boxes(k)
        self.box_vbo.write(box_vertices(boxes_rel).tobytes())
        while len(self.queries) < k:
            self.queries.append(self.ctx.query(samples=True))
        self.fbo.use()
        self.fbo.depth_mask = False
        self.ctx.depth_func = "<="
        # Front faces only: a queried box never contains the eye (that box is
        # visible by rule), so its front faces cover its whole silhouette.
        self.ctx.enable(self.ctx.CULL_FACE)
        vao, qs = self.box_vao, self.queries
        for i in range(k):                     # one GL query per box; nothing read yet
            with qs[i]:
                vao.render(vertices=36, first=36 * i)
        self.ctx.disable(self.ctx.CULL_FACE)
        self.fbo.depth_mask = True
        return np.array([qs[i].samples for i in range(k)], dtype=np.int64)

    def _reserve_boxes(self, k):
        if k <= self.box_capacity:
            return
        cap = max(64, 1 << int(np.ceil(np.log2(k))))
        if self.box_vao is not None:
            self.box_vao.release()
            self.box_vbo.release()
        self.box_vbo = self.ctx.buffer(reserve=cap * 36 * 12)
        self.box_vao = self.ctx.vertex_array(self.box_prog, [(self.box_vbo, "3f", "in_pos")])
        self.box_capacity = cap

    def finish(self):
        self.ctx.finish()

    @property
    def device(self):
        """The OpenGL renderer string (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)')."""
        return self.ctx.info.get("GL_RENDERER", "unknown")

    def read_depth(self):
        """The depth buffer, ``(height, width) float32``, row 0 at the bottom."""
        self.activate()
        data = self.depth_tex.read(alignment=1)
        return np.frombuffer(data, dtype=np.float32).reshape(self.height, self.width)

    # --- ground truth ---------------------------------------------------------
    def object_ids(self, camera, objects=None):
        """ID buffer from ``camera``: ``(height, width) int64``, -1 = none.

        objects: the objects to draw (default all of them).
        """
        self.begin_frame(camera)
        self.id_fbo.use()
        self.id_fbo.clear(depth=1.0)
        self.ctx.depth_func = "<"
        units = np.arange(len(self.units))
        if objects is not None:
            keep = np.zeros(self.n, dtype=bool)
            keep[np.asarray(objects, dtype=np.int64)] = True
            units = units[keep[self.units.object]]
        if len(units):
            self.cmd_buffer.orphan()
            self.cmd_buffer.write(self.commands[units].tobytes())
            self.id_vao.render_indirect(self.cmd_buffer, count=len(units))
        raw = self.id_fbo.read(components=1, dtype="u4", alignment=1)
        ids = np.frombuffer(raw, dtype=np.uint32).reshape(self.height, self.width)
        return ids.astype(np.int64) - 1

    def visible_truth(self, camera):
        """Exact visible set at this resolution: ``(n,) bool``, an object covers a pixel centre."""
        ids = self.object_ids(camera)
        out = np.zeros(self.n, dtype=bool)
        out[ids[ids >= 0]] = True
        return out

    def release(self):
        """Free the GPU objects (and the context when this renderer created it)."""
        self.activate()
        if self.own_ctx:
            self.ctx.release()
            return
        objs = [self.depth_vao, self.id_vao, self.box_vao, self.box_vbo, self.vbo, self.ibo,
                self.cmd_buffer, self.mvp_buffer, self.id_buffer, self.depth_prog, self.id_prog,
                self.box_prog, self.fbo, self.id_fbo, self.depth_tex]   # moderngl queries have no release
        for a in self.id_fbo.color_attachments:
            objs.append(a)
        if self.id_fbo.depth_attachment is not None:
            objs.append(self.id_fbo.depth_attachment)
        # Unbind our framebuffer first: moderngl re-binds "the current one" after
        # creating the next, and a deleted name there is GL_INVALID_OPERATION.
        self.ctx.detect_framebuffer(0).use()
        for o in objs:
            if o is not None:
                o.release()
