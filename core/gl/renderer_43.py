"""The OpenGL 4.3 path of the renderer (Linux, Windows; see :mod:`core.gl.renderer`).

A ``draw`` is one ``glMultiDrawElementsIndirect`` whose commands and per-draw MVPs go
up in one buffer write (a ring of draw data, picked by baseInstance).  A query batch
is ONE instanced draw of all its boxes (corners expanded in the vertex shader), early
depth test ``<=``, no depth or colour write; every passing fragment adds one to its
box's counter in a storage buffer (or, with ``counts=False``, sets its flag), read
back once per batch; each pending batch owns its buffer.
"""

import numpy as np

from .renderer import BaseRenderer, ceil_to, pow2

GL_BUFFER_UPDATE_BARRIER_BIT = 0x200   # shader writes visible to buffer reads/maps
SSBO_ALIGN = 256                        # >= GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT everywhere
CMD_BYTES = 20                          # one DrawElementsIndirectCommand
# Per-draw instance record of the stream: column-major MVP and object id.
RECORD = np.dtype([("mvp", "<f4", (16,)), ("id", "<u4")])
STREAM_ALIGN = 340                      # lcm(CMD_BYTES, RECORD.itemsize): a chunk starts on both
FIRST_SLOT_BOXES = 256                  # the first query slot's boxes (grown in place for larger batches)


def _counts_at(k):
    """Where a batch of ``k`` boxes keeps its counters in its slot: after its boxes."""
    return ceil_to(k * 24, SSBO_ALIGN)


class _Slot:
    """A query batch's own buffer, for batches of up to ``cap`` boxes: float32 boxes
    (lo, hi) at 0, uint counters after them (:func:`_counts_at`)."""

    def __init__(self, ctx, progs, cap):
        self.cap = cap
        self.unfenced = False           # shader writes not yet behind a memory barrier
        self.buffer = ctx.buffer(reserve=self.nbytes(cap))
        # one vertex array per box program (sample counters, flags) on the same buffer
        self.vaos = {kind: ctx.vertex_array(p, [(self.buffer, "3f 3f/i", "in_lo", "in_hi")])
                     for kind, p in progs.items()}

    @staticmethod
    def nbytes(cap):
        return _counts_at(cap) + 4 * cap

    def grow(self, cap):
        """New storage for ``cap`` boxes under the same buffer name: its vertex arrays
        stay valid, no GL object is made (a dropped batch's writes go to the old storage)."""
        self.buffer.orphan(self.nbytes(cap))
        self.cap, self.unfenced = cap, False


class Renderer43(BaseRenderer):
    """Multi-draw indirect geometry, one-draw query batches into storage buffers."""

    path = "4.3"

    def _init_path(self):
        ctx = self.ctx
        self.box_progs = {True: self.program("box_43.vert.glsl", "box_count_43.frag.glsl"),
                          False: self.program("box_43.vert.glsl", "box_flag_43.frag.glsl")}
        # The draw stream, a ring: chunks of [indirect commands | per-instance records]
        # appended frame after frame; when full it is orphaned (draws in flight keep the
        # old storage) and filled again from 0.
        self.stream_size = pow2(STREAM_ALIGN + (CMD_BYTES + RECORD.itemsize) * max(len(self.units), 1)
                                + RECORD.itemsize, least=4096)
        self.stream = ctx.buffer(reserve=self.stream_size)
        self.stream_at = 0
        self.depth_vao = ctx.vertex_array(self.depth_prog, [(self.vbo, "3f", "in_pos"),
                                                            (self.stream, "16f 4x/i", "in_mvp")],
                                          index_buffer=self.ibo, index_element_size=4)
        self.id_vao = ctx.vertex_array(self.id_prog, [(self.vbo, "3f", "in_pos"),
                                                      (self.stream, "16f u/i", "in_mvp", "in_id")],
                                       index_buffer=self.ibo, index_element_size=4)
        # The query batches' slots, made with the renderer: a batch takes the smallest
        # free slot that holds it, or grows the largest free one in place; a new slot
        # only for a batch issued while every slot holds a pending one.  A pass reads
        # each batch before the next, so a renderer keeps one slot and the GL objects
        # alive stay the same pass after pass (tools/checks/soak.py counts them every cycle).
        self.slots = [_Slot(ctx, self.box_progs, FIRST_SLOT_BOXES)]
        self.free_slots = list(self.slots)     # not holding a pending batch

    def _draw_units(self, units, ids):
        """One buffer write (commands and records) and one multi-draw."""
        vao = self.id_vao if ids else self.depth_vao
        k = len(units)
        need = STREAM_ALIGN + (CMD_BYTES + RECORD.itemsize) * k + RECORD.itemsize
        if self.stream_at + need > self.stream_size:
            self.stream_size = max(self.stream_size, pow2(need))
            self.stream.orphan(self.stream_size)           # pending draws keep the old storage
            self.stream_at = 0
            self.count_gl()
        at = self.stream_at
        rec_at = ceil_to(at + CMD_BYTES * k, RECORD.itemsize)
        end = rec_at + RECORD.itemsize * k
        blob = np.zeros(end - at, dtype=np.uint8)
        cmds = self.commands[units]
        cmds[:, 4] = rec_at // RECORD.itemsize + np.arange(k)   # baseInstance: this unit's record
        blob[:CMD_BYTES * k] = cmds.view(np.uint8).ravel()
        rec = np.zeros(k, dtype=RECORD)
        rec["mvp"] = self.mvps(units).reshape(k, 16)
        rec["id"] = self.units.object[units]
        blob[rec_at - at:] = rec.view(np.uint8)
        self.stream.write(blob, offset=at)
        vao.render_indirect(self.stream, count=k, first=at // CMD_BYTES)
        self.stream_at = ceil_to(end, STREAM_ALIGN)
        self.count_gl(2, draws=1)

    def _box_program_key(self, counts):
        return counts                  # sample counters or flags

    def _issue(self, boxes_rel, counts):
        k = len(boxes_rel)
        free = self.free_slots
        if free:
            fits = [s for s in free if s.cap >= k]
            slot = min(fits, key=lambda s: s.cap) if fits else max(free, key=lambda s: s.cap)
            free.remove(slot)
            if slot.cap < k:
                slot.grow(pow2(k))
                self.count_gl()
        else:
            slot = _Slot(self.ctx, self.box_progs, pow2(k))
            self.slots.append(slot)
        counts_at = _counts_at(k)
        if slot.unfenced:               # dropped unread: its shader writes must land before ours
            self.ctx.memory_barrier(GL_BUFFER_UPDATE_BARRIER_BIT)
            self.count_gl()
        slot.unfenced = True
        blob = np.zeros(counts_at + 4 * k, dtype=np.uint8)          # counters start at 0
        blob[:24 * k] = boxes_rel.reshape(k, 6).astype(np.float32).view(np.uint8).ravel()
        slot.buffer.write(blob)
        slot.buffer.bind_to_storage_buffer(0, offset=counts_at, size=4 * k)
        slot.vaos[counts].render(vertices=36, instances=k)
        self.count_gl(2, draws=1)

        def read():
            # The barrier here, not after the draw: it makes llvmpipe wait for the draw,
            # and the batch is only waited for when it is read.
            self.ctx.memory_barrier(GL_BUFFER_UPDATE_BARRIER_BIT)
            slot.unfenced = False
            raw = slot.buffer.read(size=4 * k, offset=counts_at)
            self.free_slots.append(slot)
            self.count_gl(2, reads=1)
            return np.frombuffer(raw, dtype=np.uint32).astype(np.int64)
        return read, lambda: self.free_slots.append(slot)

    def _path_objects(self):
        objs = [self.stream]
        for s in self.slots:
            objs += [*s.vaos.values(), s.buffer]
        return objs
