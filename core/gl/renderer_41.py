"""The OpenGL 4.1 core path of the renderer (macOS; ``OCC_GL=4.1`` anywhere; see
:mod:`core.gl.renderer`): one draw per unit with a uniform MVP, one occlusion query
object per box, one blocking read per box.  No storage buffers, no multi-draw
indirect, no baseInstance.
"""

import numpy as np

from .renderer import BaseRenderer, pow2
from .upload import box_vertices


class Renderer41(BaseRenderer):
    """A draw per unit, a query object per box."""

    path = "4.1"

    def _init_path(self):
        ctx = self.ctx
        self.box_progs = {True: self.program("box_41.vert.glsl", "depth.frag.glsl")}
        self.depth_vao = ctx.vertex_array(self.depth_prog, [(self.vbo, "3f", "in_pos")],
                                          index_buffer=self.ibo, index_element_size=4)
        self.id_vao = ctx.vertex_array(self.id_prog, [(self.vbo, "3f", "in_pos")],
                                       index_buffer=self.ibo, index_element_size=4)
        self.box_capacity = 0
        self.box_vbo = None
        self.box_vao = None
        self.free_queries = []         # query objects not held by a pending batch

    def _draw_units(self, units, ids):
        """One uniform write and one draw per unit (no multi-draw, no baseInstance)."""
        prog, vao = (self.id_prog, self.id_vao) if ids else (self.depth_prog, self.depth_vao)
        mvps = self.mvps(units)
        mvp = prog["u_mvp"]
        objs = self.units.object[units]
        for i, unit in enumerate(units.tolist()):
            mvp.write(mvps[i].tobytes())
            if ids:
                prog["u_id"].value = int(objs[i])
            cmd = self.commands[unit]
            vao.render(vertices=int(cmd[0]), first=int(cmd[2]))
        self.count_gl((3 if ids else 2) * len(units), draws=len(units))

    def _box_program_key(self, counts):
        return True                    # one box program: the query objects count samples

    def _issue(self, boxes_rel, counts):
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
        self.count_gl(1 + 3 * k, draws=k)

        def read():
            samples = np.array([q.samples for q in qs], dtype=np.int64)
            self.free_queries.extend(qs)
            self.count_gl(k, reads=k)
            return samples
        return read, lambda: self.free_queries.extend(qs)

    def _reserve_boxes(self, k):
        if k <= self.box_capacity:
            return
        cap = pow2(k)
        if self.box_vao is not None:
            self.box_vao.release()
            self.box_vbo.release()
        self.box_vbo = self.ctx.buffer(reserve=cap * 36 * 12)
        self.box_vao = self.ctx.vertex_array(self.box_progs[True], [(self.box_vbo, "3f", "in_pos")])
        self.box_capacity = cap

    def _path_objects(self):
        return [self.box_vao, self.box_vbo]           # moderngl queries have no release
