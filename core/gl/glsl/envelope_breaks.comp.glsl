// The envelope's first pass, one thread per pixel: the view-space depth of the pixel's
// first surface from the window depth, and whether the pixel is a break (empty, nearer
// than the nearest depth that covers, or beside a depth jump no continuous surface
// makes: core/envelope.py's _jumps).  Writes (-z, z) per pixel, z = +inf for a break:
// the window maxima of the next pass then say both "the nearest depth" and "a break in
// the window" (+inf).  It also opens every pixel of the extended depth (+inf): no
// clear of that buffer from the CPU (a mapped write of the whole image).
#include "envelope_common.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;
uniform double u_c1, u_c2, u_c3;   // z = c1 / (c2 - ndc c3): 2 near far, far + near, far - near
uniform double u_near_eff;         // nearer surfaces cover nothing
uniform float u_wtol;              // 1/z steps this close pass for one slope
uniform int u_jumps;               // distance > 0: look for jumps
layout(std430, binding = OUT_BINDING) writeonly buffer Out { vec2 zz[]; };
layout(std430, binding = EXT_BINDING) writeonly buffer Ext { float ext[]; };

bool depth_at(ivec2 p, out double z) {
    float d = texelFetch(u_depth, p, 0).r;
    precise double ndc = 2.0LF * double(d) - 1.0LF;
    precise double den = u_c2 - ndc * u_c3;
    z = u_c1 / den;
    return d < 1.0 && z > u_near_eff;
}

float inv(double z) { precise double w = 1.0LF / z; return float(w); }

// whether the pair (a, a + e) is a jump: both pixels then break
bool jump(ivec2 a, ivec2 e) {
    ivec2 b = a + e;
    double za, zb;
    bool oa = depth_at(a, za), ob = depth_at(b, zb);
    if (!(oa && ob)) return true;
    precise float step = inv(zb) - inv(za);
    bool has_before = false, has_after = false;
    float before = 0.0, after = 0.0;
    double zp, zq;
    if (inside(a - e) && depth_at(a - e, zp)) { precise float s = inv(za) - inv(zp); before = s; has_before = true; }
    if (inside(b + e) && depth_at(b + e, zq)) { precise float s = inv(zq) - inv(zb); after = s; has_after = true; }
    if (has_before || has_after) {
        float lo = has_before && has_after ? min(before, after) : has_before ? before : after;
        float hi = has_before && has_after ? max(before, after) : has_before ? before : after;
        precise float lo_t = lo - u_wtol;
        precise float hi_t = hi + u_wtol;
        if (step >= lo_t && step <= hi_t) return false;
    }
    return true;                   // however small the step: a sub-pixel gap may lie between
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p)) return;
    ext[at(p)] = INF;
    double z;
    if (!depth_at(p, z)) { zz[at(p)] = vec2(-INF, INF); return; }
    bool brk = false;
    if (u_jumps != 0) {
        for (int axis = 0; axis < 2 && !brk; ++axis) {
            ivec2 e = axis == 0 ? ivec2(0, 1) : ivec2(1, 0);
            brk = (inside(p - e) && jump(p - e, e)) || (inside(p + e) && jump(p, e));
        }
    }
    float zf = float(z);
    zz[at(p)] = vec2(-zf, brk ? INF : zf);
}
