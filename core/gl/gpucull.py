"""A GPU-resident culling pass (the ``gpu`` strategy's GL side; 4.3 path only).

Every draw unit's world box and world matrix live on the GPU (float64, uploaded by
:meth:`GpuCull.upload` after a rebuild or ``set_matrices``); a pass is a few
compute dispatches and indirect draws whose commands the GPU writes, and ONE
read-back of a word per unit:

1. ``prepare`` (compute, one thread per unit): frustum test of the camera-relative
   box (float64, the CPU's rule and tolerance), the query box grown by the engine's
   guard (:meth:`core.traversal.Frame.guard`: half a query pixel + 2 depth steps,
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
"""

import numpy as np

from ..tolerance import tol
from . import shaders as S

LOCAL = 64                                 # compute work-group size
# Bits of a unit's word (the read-back): the state in bits 0-1 (core.traversal.Visibility)
STATE, INF, NEAR, DRAWN1, DRAWN2, TESTED1, TESTED2, PREV, HIZ = 3, 4, 8, 16, 32, 64, 128, 256, 512
UNIT_BYTES = 192                           # dmat4 world, dvec4 lo (w: valid), dvec4 hi
DYN_BYTES = 96                             # mat4 mvp, vec4 grown lo, vec4 grown hi
HEADER = 128                               # params: 2 box-draw commands, the unit count, float32 view-projection
PARAMS = 64                                # doubles after the header
# word arrays of the words buffer, in units of U: state, the box tests' flags and lists
STATE_AT, FLAG1_AT, FLAG2_AT, LIST1_AT, LIST2_AT = range(5)
ALL_BARRIERS = 0xFFFFFFFF
# The pyramid test reads the finest level where the box's rectangle spans at most this many
# texels a side (level 2 whatever the span): 8 drew 206 units on city-xl where 4 drew 252.
HIZ_SPAN = 8
DEPTH_UNIT = 7                             # texture unit of the depth the pyramid reads (the renderer uses 0)

_COMMON = """{v}
#define STATE 3u
#define INF 4u
#define NEAR 8u
#define DRAWN1 16u
#define DRAWN2 32u
#define TESTED1 64u
#define TESTED2 128u
#define PREV 256u
#define HIZ 512u
struct Unit { dmat4 world; dvec4 lo; dvec4 hi; };
struct Dyn { mat4 mvp; vec4 glo; vec4 ghi; };
layout(std430, binding = 1) buffer Params { uint hdr[16]; mat4 vp; double f[]; };
// hdr: the box-draw commands of the two box tests at 0-3 and 5-8 (moderngl reads indirect
// commands at a stride of 20 bytes for both kinds of draw), the unit count at 12
#define N_UNITS hdr[12]
layout(std430, binding = 2) readonly buffer Units { Unit units[]; };
layout(std430, binding = 3) buffer Dyns { Dyn dyn[]; };
layout(std430, binding = 4) buffer Words { uint w[]; };
layout(std430, binding = 5) buffer Cmds { uint c[]; };
// the max-depth pyramid of pass 1's depth: levels 1 and 2 (4 and 16 pixels a texel side), level 0
// is the depth texture itself
layout(std430, binding = 6) buffer Hiz { float z[]; };
uniform sampler2D u_depth;
// f: eye 0-2, clip 4-19 (column-major), planes 20-43, then the scalars below
#define PLANE_REL f[44]
#define NEAR_REL f[45]
#define GROW_REL f[46]
#define GROW_ABS f[47]
#define LATERAL f[48]
#define PERSPECTIVE f[49]
#define TIE f[50]
#define EXTENT f[51]
#define TINY f[52]
#define DIR dvec3(f[53], f[54], f[55])
"""

_COMPUTE_HEAD = _COMMON + """
layout(local_size_x = %d) in;
// a compute pass: one thread per unit u of the n
#define EACH_UNIT uint n = N_UNITS; uint u = gl_GlobalInvocationID.x; if (u >= n) return;
double maxabs(dvec3 a) { dvec3 b = abs(a); return max(b.x, max(b.y, b.z)); }
dmat4 clip() { return dmat4(f[4], f[5], f[6], f[7], f[8], f[9], f[10], f[11],
                            f[12], f[13], f[14], f[15], f[16], f[17], f[18], f[19]); }
dvec4 plane(int k) { return dvec4(f[20 + 4 * k], f[21 + 4 * k], f[22 + 4 * k], f[23 + 4 * k]); }
// the unit's MVP: float64 camera-relative, then float32 (the renderer's precision rule)
void set_mvp(uint u) {
    dmat4 m = units[u].world;
    m[3].xyz -= dvec3(f[0], f[1], f[2]);
    dyn[u].mvp = mat4(clip() * m);
}
""" % LOCAL

PREPARE = _COMPUTE_HEAD + """

// Frame.guard, per axis: relative + pixel guard across the rays + depth steps along them
dvec3 guard(dvec3 lo, dvec3 hi) {
    double mag = max(maxabs(lo), maxabs(hi));
    dvec3 e = hi - lo;
    double base = GROW_REL * (mag + max(e.x, max(e.y, e.z))) + GROW_ABS;
    dvec3 vmin, vmax;
    double lateral, tie;
    if (PERSPECTIVE > 0.5) {
        dvec3 wrow = dvec3(f[7], f[11], f[15]);
        double w3 = f[19];
        bvec3 pos = greaterThanEqual(wrow, dvec3(0.0));
        double far_w = max(dot(mix(lo, hi, pos), wrow) + w3, 0.0);
        double near_w = dot(mix(hi, lo, pos), wrow) + w3;
        lateral = LATERAL * far_w;
        bvec3 spans = bvec3(lo.x <= 0.0 && hi.x >= 0.0, lo.y <= 0.0 && hi.y >= 0.0, lo.z <= 0.0 && hi.z >= 0.0);
        dvec3 near_abs = mix(min(abs(lo), abs(hi)), dvec3(0.0), spans);
        dvec3 far_abs = max(abs(lo), abs(hi));
        double far_norm = sqrt(dot(far_abs, far_abs));
        double near_norm = sqrt(dot(near_abs, near_abs));
        vmin = near_abs / max(far_norm, TINY);
        vmax = min(far_abs / max(near_norm, TINY), dvec3(1.0));
        tie = TIE * far_w * far_w * far_norm / max(near_w, TINY + 1e-12lf * far_norm);
    } else {
        lateral = LATERAL;
        vmin = vmax = DIR;
        tie = TIE;
    }
    dvec3 across = sqrt(max(dvec3(1.0) - vmin * vmin, dvec3(0.0)));
    return dvec3(base) + lateral * across + tie * vmax;
}

void main() {
    EACH_UNIT
    uint prev = w[u] & PREV;
    w[%(flag1)d * n + u] = 0u;
    w[%(flag2)d * n + u] = 0u;
    c[5u * u + 1u] = 0u;
    c[5u * (n + u) + 1u] = 0u;
    Unit un = units[u];
    if (un.lo.w == 0.0) { w[u] = 2u; return; }            // invalid: never drawn, never tested
    dvec3 eye = dvec3(f[0], f[1], f[2]);
    dvec3 lo = un.lo.xyz - eye, hi = un.hi.xyz - eye;
    double scale = max(maxabs(lo), maxabs(hi));
    for (int k = 0; k < 6; ++k) {
        dvec4 p = plane(k);
        // outside only beyond the plane tolerance (classify_fast's rule)
        double dp = dot(max(p.xyz, dvec3(0.0)), hi) + dot(min(p.xyz, dvec3(0.0)), lo) + p.w;
        if (dp < -PLANE_REL * (scale + abs(p.w))) { w[u] = 2u; return; }
    }
    dvec3 g = guard(lo, hi);
    dvec3 glo = lo - g, ghi = hi + g;
    // Conservative: a grown box that reaches the near plane is visible without a test
    dvec4 np = plane(4);
    bvec3 npos = greaterThanEqual(np.xyz, dvec3(0.0));
    double lowest = dot(mix(ghi, glo, npos), np.xyz) + np.w;
    bool near = lowest <= NEAR_REL * max(maxabs(glo), maxabs(ghi));
    dyn[u].glo = vec4(clamp(glo, dvec3(-EXTENT), dvec3(EXTENT)), 0.0);
    dyn[u].ghi = vec4(clamp(ghi, dvec3(-EXTENT), dvec3(EXTENT)), 0.0);
    uint bits = prev | INF | (near ? NEAR : 0u);
    if (prev != 0u || near) {
        bits |= DRAWN1;
        c[5u * u + 1u] = 1u;
        set_mvp(u);
    } else {
        bits |= TESTED1;
    }
    w[u] = bits;
}
""" % {"flag1": FLAG1_AT, "flag2": FLAG2_AT}

# One dispatch builds levels 1 and 2 (each texel the FARTHEST depth of the pixels it
# covers: conservative), one thread per level-2 texel (16 x 16 pixels), no barriers.
# textureGather at a texel corner reads the 2 x 2 pixels around it; at the image's
# right or top edge it wraps to pixels of the other side: a larger maximum, conservative.
PYRAMID = _COMMON + """
layout(local_size_x = 8, local_size_y = 8) in;
void main() {
    ivec2 size = textureSize(u_depth, 0);
    ivec2 s1z = (size + 3) / 4, s2z = (s1z + 3) / 4;
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (t.x >= s2z.x || t.y >= s2z.y) return;
    vec2 texel = 1.0 / vec2(size);
    float m2 = 0.0;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            ivec2 l1 = 4 * t + ivec2(i, j);
            if (l1.x >= s1z.x || l1.y >= s1z.y) continue;
            float m = 0.0;
            for (int b = 1; b < 4; b += 2)
                for (int a = 1; a < 4; a += 2) {
                    vec4 g = textureGather(u_depth, vec2(4 * l1 + ivec2(a, b)) * texel);
                    m = max(m, max(max(g.x, g.y), max(g.z, g.w)));
                }
            z[l1.y * s1z.x + l1.x] = m;
            m2 = max(m2, m);
        }
    z[s1z.x * s1z.y + t.y * s2z.x + t.x] = m2;
}
"""

SECOND = _COMPUTE_HEAD + """
#define SPAN %(span)d
// The farthest depth of pixels [lo, hi] (inclusive) at the finest level where the
// rectangle spans at most SPAN texels a side (or level 2).
float farthest(ivec2 lo, ivec2 hi) {
    ivec2 size = textureSize(u_depth, 0);
    int level = 0;
    while (level < 2 && any(greaterThan((hi >> (2 * level)) - (lo >> (2 * level)), ivec2(SPAN - 1)))) ++level;
    float m = 0.0;
    if (level == 0) {
        for (int y = lo.y; y <= hi.y; ++y)
            for (int x = lo.x; x <= hi.x; ++x) m = max(m, texelFetch(u_depth, ivec2(x, y), 0).r);
        return m;
    }
    int at = 0;
    ivec2 sz = size;
    for (int k = 1; k <= level; ++k) {
        sz = (sz + 3) / 4;
        if (k < level) at += sz.x * sz.y;
    }
    ivec2 a = lo >> (2 * level), b = hi >> (2 * level);
    for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x) m = max(m, z[at + y * sz.x + x]);
    return m;
}

// Whether the grown box of unit u may have a sample nearer than pass 1's depth:
// conservative, its pixel rectangle rounded outward holds every pixel centre it
// covers, and its nearest depth is compared with the farthest depth there (ties visible).
bool passes(uint u) {
    dvec3 lo = dvec3(dyn[u].glo.xyz), hi = dvec3(dyn[u].ghi.xyz);
    dmat4 C = clip();
    dvec4 base = C * dvec4(lo, 1.0);
    dvec4 ex = C[0] * (hi.x - lo.x), ey = C[1] * (hi.y - lo.y), ez = C[2] * (hi.z - lo.z);
    dvec3 a = dvec3(1e300lf), b = dvec3(-1e300lf);     // lf: double literals
    for (int k = 0; k < 8; ++k) {
        dvec4 p = base + ((k & 1) != 0 ? ex : dvec4(0.0)) + ((k & 2) != 0 ? ey : dvec4(0.0))
                       + ((k & 4) != 0 ? ez : dvec4(0.0));
        if (p.w <= 0.0) return true;
        dvec3 ndc = p.xyz / p.w;
        a = min(a, ndc);
        b = max(b, ndc);
    }
    ivec2 size = textureSize(u_depth, 0);
    dvec2 s = dvec2(size);
    dvec2 pa = (a.xy * 0.5 + 0.5) * s - 0.5, pb = (b.xy * 0.5 + 0.5) * s - 0.5;
    if (any(greaterThan(pa, s)) || any(lessThan(pb, dvec2(-1.0)))) return true;   // off screen: no sample; kept
    pa = max(pa, dvec2(-1.0));                       // in range of int before the conversion
    pb = min(pb, s);
    ivec2 lo_px = clamp(ivec2(floor(pa)), ivec2(0), size - 1);
    ivec2 hi_px = clamp(ivec2(ceil(pb)), ivec2(0), size - 1);
    double nearest = a.z * 0.5 + 0.5;
    // a shader's read of the 24-bit depth may round it a step nearer (the driver's choice,
    // as in the renderer's reduction): one step added, conservative
    return nearest <= double(farthest(lo_px, hi_px)) + 1.0lf / 16777215.0lf;
}

void main() {
    EACH_UNIT
    uint bits = w[u];
    if ((bits & INF) == 0u) return;
    if ((bits & TESTED1) != 0u && passes(u)) {
        w[u] = bits | HIZ;                           // the box test against pass 1's depth decides
        w[%(list1)d * n + atomicAdd(hdr[1], 1u)] = u;
    }
}
""" % {"list1": LIST1_AT, "span": HIZ_SPAN}

# Units whose box passed both tests against pass 1's depth are drawn in pass 2; every
# unit drawn and not near joins the list of test 2.
THIRD = _COMPUTE_HEAD + """
void main() {
    EACH_UNIT
    uint bits = w[u];
    if ((bits & INF) == 0u) return;
    if ((bits & HIZ) != 0u && w[%(flag1)d * n + u] != 0u) {
        bits |= DRAWN2;
        c[5u * (n + u) + 1u] = 1u;
        set_mvp(u);
    }
    if ((bits & (DRAWN1 | DRAWN2)) != 0u && (bits & NEAR) == 0u) {
        bits |= TESTED2;
        w[%(list2)d * n + atomicAdd(hdr[6], 1u)] = u;
    }
    w[u] = bits;
}
""" % {"flag1": FLAG1_AT, "list2": LIST2_AT}

FINAL = _COMPUTE_HEAD + """
void main() {
    EACH_UNIT
    uint bits = w[u] & ~(STATE | PREV);
    if ((bits & INF) == 0u) { w[u] = bits | 2u; return; }
    // VISIBLE: near (by rule) or its box passed the test against the completed depth;
    // OCCLUDED: its box failed a test against real geometry (test 1 or test 2)
    bool visible = (bits & NEAR) != 0u || ((bits & TESTED2) != 0u && w[%(flag2)d * n + u] != 0u);
    w[u] = bits | (visible ? PREV : 1u);
}
""" % {"flag2": FLAG2_AT}

# The box test: list k's boxes, one instance each, corners from gl_VertexID (as the
# renderer's BOX_VERTEX_43), front faces only, early depth test <=, no depth write.
BOX_VERTEX = _COMMON + """
flat out uint v_unit;
const int CORNER[36] = int[36](%s);
void main() {
    uint u = w[LIST * N_UNITS + uint(gl_InstanceID)];
    v_unit = u;
    vec4 lo = dyn[u].glo, hi = dyn[u].ghi;
    int k = CORNER[gl_VertexID];
    vec3 p = vec3((k & 1) != 0 ? hi.x : lo.x, (k & 2) != 0 ? hi.y : lo.y, (k & 4) != 0 ? hi.z : lo.z);
    gl_Position = vp * vec4(p, 1.0);
}
""" % ", ".join(str(int(i)) for i in S.BOX_TRIANGLES)
BOX_FRAGMENT = _COMMON + """
layout(early_fragment_tests) in;
flat in uint v_unit;
void main() { w[FLAG * N_UNITS + v_unit] = 1u; }
"""


def _nothing(_stage):
    pass


def for_renderer(renderer):
    """``(GpuCull, None)`` for a 4.3 renderer (made once per renderer and shared by the
    strategies that use it: the shaders compile once), or ``(None, reason)`` where the
    driver refuses the shaders (float64 in compute shaders is required)."""
    import moderngl
    gpu = getattr(renderer, "gpu_cull", None)
    if gpu is None:
        try:
            gpu = renderer.gpu_cull = GpuCull(renderer)
        except moderngl.Error as e:
            return None, f"the GPU culling shaders do not compile here: {e}"
    return gpu, None


class GpuCull:
    """The GPU-resident buffers and programs of the ``gpu`` strategy for one renderer
    (4.3 path).  ``units`` of the renderer; boxes from :meth:`upload`."""

    def __init__(self, renderer):
        r = self.r = renderer
        ctx = self.ctx = renderer.ctx
        r.activate()
        self.n = n = len(r.units)
        cap = max(n, 1)

        def program(vertex, fragment, **defines):
            head = "".join(f"#define {k} {v}u\n" for k, v in defines.items())
            return ctx.program(vertex_shader=S.source(vertex, "4.3").replace("\n", "\n" + head, 1),
                               fragment_shader=S.source(fragment, "4.3").replace("\n", "\n" + head, 1))

        self.prepare = ctx.compute_shader(S.source(PREPARE, "4.3"))
        self.pyramid = ctx.compute_shader(S.source(PYRAMID, "4.3"))
        self.second = ctx.compute_shader(S.source(SECOND, "4.3"))
        self.third = ctx.compute_shader(S.source(THIRD, "4.3"))
        self.final = ctx.compute_shader(S.source(FINAL, "4.3"))
        for cs in (self.pyramid, self.second):
            cs["u_depth"].value = DEPTH_UNIT
        self.box_progs = [program(BOX_VERTEX, BOX_FRAGMENT, LIST=LIST1_AT, FLAG=FLAG1_AT),
                          program(BOX_VERTEX, BOX_FRAGMENT, LIST=LIST2_AT, FLAG=FLAG2_AT)]
        r.depth_tex.compare_func = ""                  # texelFetch reads depth values
        size = np.array([r.width, r.height])
        levels = [(size + 3) // 4]
        levels.append((levels[-1] + 3) // 4)
        self.levels = [(int(a), int(b)) for a, b in levels]
        self.pyramid_groups = tuple(int(v) for v in (levels[-1] + 7) // 8)     # 128 x 128 pixels a group
        self.hiz = ctx.buffer(reserve=4 * int(sum(int(a * b) for a, b in levels)))
        self.params = ctx.buffer(reserve=HEADER + 8 * PARAMS)
        self.unit_buf = ctx.buffer(reserve=UNIT_BYTES * cap)
        self.dyn = ctx.buffer(reserve=DYN_BYTES * cap)
        self.words = ctx.buffer(reserve=4 * 5 * cap)
        self.words.clear()
        # commands of pass 1 at [0, n), of pass 2 at [n, 2n): the renderer's, baseInstance = unit
        cmds = np.zeros((2, cap, 5), dtype=np.uint32)
        if n:
            cmds[:, :n] = r.commands
            cmds[:, :n, 1] = 0
            cmds[:, :n, 4] = np.arange(n, dtype=np.uint32)
        self.cmds = ctx.buffer(cmds.tobytes())
        self.draw_vao = ctx.vertex_array(r.depth_prog, [(r.vbo, "3f", "in_pos"), (self.dyn, "16f 32x/i", "in_mvp")],
                                         index_buffer=r.ibo, index_element_size=4)
        self.box_vaos = [ctx.vertex_array(p, []) for p in self.box_progs]
        self.groups = max(1, -(-n // LOCAL))
        self.uploaded = False

    def upload(self, boxes, valid, world, units=None):
        """World boxes ``(k, 2, 3) float64``, ``valid (k,) bool`` and world matrices of
        the units' objects (mesh centre folded in) ``(k, 4, 4) float64`` of ``units``
        (default all, ``k = n``): one write per run of consecutive units."""
        units = np.arange(self.n) if units is None else np.asarray(units, dtype=np.int64)
        k = len(units)
        if not k:
            return
        data = np.zeros((k, UNIT_BYTES // 8), dtype=np.float64)
        data[:, :16] = np.asarray(world, dtype=np.float64).transpose(0, 2, 1).reshape(k, 16)   # column-major
        ok = valid & np.isfinite(boxes).all(axis=(1, 2)) & (boxes[:, 0] <= boxes[:, 1]).all(axis=1)
        data[:, 16:19] = np.where(ok[:, None], boxes[:, 0], 0.0)
        data[:, 19] = ok
        data[:, 20:23] = np.where(ok[:, None], boxes[:, 1], 0.0)
        self.r.activate()
        starts = np.flatnonzero(np.r_[True, np.diff(units) != 1])
        for a, b in zip(starts, np.r_[starts[1:], k], strict=True):
            self.unit_buf.write(data[a:b].tobytes(), offset=UNIT_BYTES * int(units[a]))
        self.r._count(len(starts))
        self.uploaded = True

    def remember(self, visible):
        """Set the memory (what pass 1 draws) to ``visible (n,) bool``: one write."""
        self.r.activate()
        self.words.write(np.where(visible, PREV, 0).astype(np.uint32).tobytes())
        self.r._count()

    def forget(self):
        self.remember(np.zeros(self.n, dtype=bool))

    def params_blob(self, frame, pixels):
        """The per-pass parameters: the header (box-draw commands zeroed, unit count,
        float32 view-projection) and the float64 values of the module doc."""
        r = self.r
        head = np.zeros(HEADER // 4, dtype=np.uint32)
        head[0] = head[5] = 36                         # box draws: 36 vertices, instances counted by the GPU
        head[12] = self.n
        head[16:32] = np.ascontiguousarray(r.clip.T, dtype=np.float32).ravel().view(np.uint32)
        f = np.zeros(PARAMS, dtype=np.float64)
        f[0:3] = r.eye
        f[4:20] = r.clip.T.ravel()
        f[20:44] = frame.planes.ravel()
        f[44], f[45], f[46] = tol.plane_rel, tol.near_guard_rel, tol.box_grow_rel
        f[47] = tol.box_grow_scene * frame.scene_size
        f[48] = pixels * frame.pixel_world
        f[49] = 1.0 if frame.perspective else 0.0
        f[50] = tol.depth_guard_steps * frame.depth_step
        f[51] = r.view_extent
        f[52] = 1e-300
        f[53:56] = np.abs(frame.camera.direction)
        return head.tobytes() + f.tobytes()

    def run(self, frame, pixels, stage=None):
        """One pass from the frame's camera (the renderer's ``begin_frame`` done):
        returns the word of every unit, ``(n,) uint32`` (module doc).  ``stage``:
        called with each stage's name once its GL work is issued (a profiler's hook,
        tools/gpu_stages.py)."""
        r, ctx, n = self.r, self.ctx, self.n
        done = stage or _nothing
        r.activate()
        self.params.write(self.params_blob(frame, pixels))
        self.bind()
        done("params")
        self.prepare.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        r._count(9)                            # params, 6 bindings, dispatch, barrier
        done("prepare (frustum, guard)")
        self._draw(0)
        if r.reduces:                          # the whole screen: what the GPU drew is not known here
            r._dirty = np.array([0, 0, r.width - 1, r.height - 1])
            r._reduce()
        done("draw 1 (last visible)")
        self.build_pyramid()
        done("pyramid")
        self.second.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        r._count(5)
        done("second (pyramid test)")
        self._test(0)                          # pass 1's depth: reduced already
        done("box test 1")
        self.third.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        r._count(2)
        done("third")
        self._draw(n)
        if r.reduces:
            r._dirty = np.array([0, 0, r.width - 1, r.height - 1])
            r._reduce()
        done("draw 2 (newly visible)")
        self._test(1)
        done("box test 2")
        self.final.run(self.groups)
        ctx.memory_barrier(ALL_BARRIERS)
        done("final")
        words = np.frombuffer(self.words.read(size=4 * n), dtype=np.uint32)
        r._count(3, reads=1)
        r.counters["query_batches"] += 3
        done("read")
        return words

    def bind(self):
        """Bind the storage buffers (binding points 1-6; the renderer's queries use 0)."""
        for binding, buf in enumerate((self.params, self.unit_buf, self.dyn, self.words, self.cmds, self.hiz),
                                      start=1):
            buf.bind_to_storage_buffer(binding)

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
        r = self.r
        r._use(r.fbo, "<", False)
        self.draw_vao.render_indirect(self.cmds, count=self.n, first=first)
        r._count(1, draws=1)

    def _test(self, k):
        r = self.r
        r._use(r.query_fbo, "<=", True)
        self.box_vaos[k].render_indirect(self.params, mode=self.ctx.TRIANGLES, count=1, first=k)
        # the flags written by the boxes' fragments before the compute pass that reads them
        self.ctx.memory_barrier(ALL_BARRIERS)
        r._count(2, draws=1)

    def release(self):
        for o in (*self.box_vaos, self.draw_vao, self.prepare, self.pyramid, self.second, self.third, self.final,
                  *self.box_progs,
                  self.params, self.unit_buf, self.dyn, self.words, self.cmds, self.hiz):
            o.release()
