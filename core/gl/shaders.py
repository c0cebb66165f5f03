"""GLSL of both GL paths.  ``{v}`` is the ``#version`` line of the path.

Conventions: positions are camera-relative (world - eye) rounded to float32 after
float64 math on the CPU; depth test ``<`` for geometry, ``<=`` for query boxes
(ties count as visible); query boxes write neither depth nor colour.
"""

import numpy as np

VERSION = {"4.3": "#version 430 core", "4.1": "#version 410 core"}

# 12 triangles of a box, counter-clockwise seen from outside, as indices into
# bounds.corners' bit order (x=1, y=2, z=4).
BOX_TRIANGLES = np.array([
    0, 2, 1, 1, 2, 3,   4, 5, 6, 5, 7, 6,   0, 1, 4, 1, 5, 4,
    2, 6, 3, 3, 6, 7,   0, 4, 2, 2, 4, 6,   1, 3, 5, 3, 7, 5,
], dtype=np.intp)

# --- scene geometry ---------------------------------------------------------------
# 4.3: the MVP (and object id) is per-instance data of this draw, picked by baseInstance.
SCENE_VERTEX_43 = """{v}
in vec3 in_pos;
in mat4 in_mvp;
void main() { gl_Position = in_mvp * vec4(in_pos, 1.0); }
"""
ID_VERTEX_43 = """{v}
in vec3 in_pos;
in mat4 in_mvp;
in uint in_id;
flat out uint v_id;
void main() {
    gl_Position = in_mvp * vec4(in_pos, 1.0);
    v_id = in_id + 1u;
}
"""
# 4.1: one draw per unit, the MVP (and id) as uniforms.
SCENE_VERTEX_41 = """{v}
in vec3 in_pos;
uniform mat4 u_mvp;
void main() { gl_Position = u_mvp * vec4(in_pos, 1.0); }
"""
ID_VERTEX_41 = """{v}
in vec3 in_pos;
uniform mat4 u_mvp;
uniform uint u_id;
flat out uint v_id;
void main() {
    gl_Position = u_mvp * vec4(in_pos, 1.0);
    v_id = u_id + 1u;
}
"""
DEPTH_FRAGMENT = """{v}
void main() {}
"""
ID_FRAGMENT = """{v}
flat in uint v_id;
out uint f_id;
void main() { f_id = v_id; }
"""

# --- query boxes -----------------------------------------------------------------
# 4.3: one instance per box; the 36 corners come from the box's lo/hi by gl_VertexID,
# so a batch is one draw whatever its size.
BOX_VERTEX_43 = """{v}
in vec3 in_lo;
in vec3 in_hi;
uniform mat4 u_vp;
flat out int v_box;
const int CORNER[36] = int[36](%s);
void main() {
    int c = CORNER[gl_VertexID];
    // a corner takes each coordinate from lo or hi exactly (no arithmetic on it)
    vec3 p = vec3((c & 1) != 0 ? in_hi.x : in_lo.x,
                  (c & 2) != 0 ? in_hi.y : in_lo.y,
                  (c & 4) != 0 ? in_hi.z : in_lo.z);
    gl_Position = u_vp * vec4(p, 1.0);
    v_box = gl_InstanceID;
}
""" % ", ".join(str(int(i)) for i in BOX_TRIANGLES)
# Only fragments that passed the depth test run (early tests), each adds one sample to
# its box: the same count a GL_SAMPLES_PASSED query gives for a single-sampled target.
BOX_COUNT_FRAGMENT_43 = """{v}
layout(early_fragment_tests) in;
flat in int v_box;
layout(std430, binding = 0) buffer Samples { uint samples[]; };
void main() { atomicAdd(samples[v_box], 1u); }
"""
# The flag variant (what the engine uses unless a visible threshold needs counts; the README's GL figures).
BOX_FLAG_FRAGMENT_43 = """{v}
layout(early_fragment_tests) in;
flat in int v_box;
layout(std430, binding = 0) buffer Samples { uint samples[]; };
void main() { samples[v_box] = 1u; }
"""
# 4.1: triangle-list vertices of every box in one buffer, one query object per box.
BOX_VERTEX_41 = """{v}
in vec3 in_pos;
uniform mat4 u_vp;
void main() { gl_Position = u_vp * vec4(in_pos, 1.0); }
"""

# --- conservative depth reduction (display -> query resolution) -------------------
FULLSCREEN_VERTEX = """{v}
void main() {
    vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID >> 1) * 4 - 1));
    gl_Position = vec4(p, 0.0, 1.0);
}
"""
# Each query pixel takes the FARTHEST depth of every display pixel its area overlaps:
# conservative, a gap open at display resolution stays open at query resolution.
# Both depth buffers are 24-bit and a value read and written back goes through float
# (llvmpipe rounds it 0 or 1 step farther; a driver may round nearer), so one step is
# added: conservative, the reduced depth is never nearer than the display's.
REDUCE_FRAGMENT = """{v}
const float DEPTH_STEP = 1.0 / 16777215.0;
uniform sampler2D u_depth;
uniform ivec2 u_display;
uniform ivec2 u_query;
void main() {
    ivec2 q = ivec2(gl_FragCoord.xy);
    ivec2 lo = (q * u_display) / u_query;
    ivec2 hi = ((q + 1) * u_display + u_query - 1) / u_query;     // exclusive
    float d = 0.0;
    for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x)
            d = max(d, texelFetch(u_depth, ivec2(x, y), 0).r);
    gl_FragDepth = min(d + DEPTH_STEP, 1.0);
}
"""


# The same for a display that is an even multiple (rx, ry) of the query resolution in
# both axes (1280x720 over 640x360): one textureGather per 2x2 display pixels, 6-9x
# faster than the loop above on llvmpipe; the same values.
REDUCE_GATHER_FRAGMENT = """{v}
const float DEPTH_STEP = 1.0 / 16777215.0;
uniform sampler2D u_depth;
uniform vec2 u_texel;               // 1 / display size
const int RX = %(rx)d;
const int RY = %(ry)d;
void main() {
    ivec2 q = ivec2(gl_FragCoord.xy) * ivec2(RX, RY);
    float d = 0.0;
    for (int j = 0; j < RY; j += 2)
        for (int i = 0; i < RX; i += 2) {
            // the shared corner of display pixels q + (i, j) .. q + (i + 1, j + 1)
            vec4 g = textureGather(u_depth, vec2(q + ivec2(i + 1, j + 1)) * u_texel);
            d = max(d, max(max(g.x, g.y), max(g.z, g.w)));
        }
    gl_FragDepth = min(d + DEPTH_STEP, 1.0);
}
"""


def source(text, path):
    """``text`` with the path's ``#version`` line."""
    return text.replace("{v}", VERSION[path])
