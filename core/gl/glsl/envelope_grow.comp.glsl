// One axis of one window size of the envelope (core/envelope.py's _shift_max), one
// thread per pixel: the max over the pixel and its two neighbours k pixels away along
// the axis, +inf past the border (a break: nothing known there).  After the second
// axis of a size (u_eval), a pixel still open whose window holds no break and whose
// nearest depth lets the window hold its parallax takes the window's farthest depth.
#include "envelope_common.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
uniform int u_axis;        // 0: along rows (y), 1: along columns (x)
uniform int u_k;           // (h + 1) / 2
uniform int u_h;           // the window's half-size
uniform int u_eval;
uniform float u_dguard;    // the nearest depth must pass distance x guard
uniform float u_d, u_d2;   // distance, distance^2 (float)
uniform float u_diag;      // h dt sqrt(2), float
uniform float u_slack;     // 1 + 1e-5, float
uniform float u_dt32;
layout(std430, binding = SRC_BINDING) readonly buffer Src { vec2 src[]; };
layout(std430, binding = DST_BINDING) writeonly buffer Dst { vec2 dst[]; };
layout(std430, binding = EXT_BINDING) buffer Ext { float ext[]; };

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p)) return;
    ivec2 e = u_axis == 0 ? ivec2(0, 1) : ivec2(1, 0);
    int n = u_axis == 0 ? u_size.y : u_size.x;
    int i = u_axis == 0 ? p.y : p.x;
    vec2 v = src[at(p)];
    vec2 fill = vec2(INF);
    if (u_k >= n) {
        v = max(v, fill);
    } else {
        v = max(v, i >= u_k ? src[at(p - u_k * e)] : fill);
        v = max(v, i < n - u_k ? src[at(p + u_k * e)] : fill);
    }
    dst[at(p)] = v;
    if (u_eval == 0) return;
    int idx = at(p);
    float nearest = -v.x;
    if (!(ext[idx] == INF && v.y != INF && nearest > u_dguard)) return;
    // the parallax angle's tangent, the window's outer corner, the angle in pixels there
    precise float nn = nearest * nearest - u_d2;
    precise float ta = u_d / sqrt(nn);
    precise float tt = tangent(p) + u_diag;
    precise float denom = 1.0 - tt * ta;
    if (!(denom > 1e-6)) return;
    precise float r = (tt + ta) / denom;
    precise float need = ta * (1.0 + r * r) * u_slack / u_dt32 + 1.0;
    if (need <= float(u_h)) ext[idx] = v.y;
}
