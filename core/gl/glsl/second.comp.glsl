// Test 1's first half: each unit marked for it is tested against the pyramid; those
// that pass join list 1, whose boxes box test 1 draws.
#include "cull_unit.glsl"
#include "layout/depth.glsl"
uniform sampler2D u_depth;

// The farthest depth of pixels [lo, hi] (inclusive) at the finest level where the
// rectangle spans at most HIZ_SPAN texels a side (or level 2).
float farthest(ivec2 lo, ivec2 hi) {
    ivec2 size = textureSize(u_depth, 0);
    int level = 0;
    while (level < 2 && any(greaterThan((hi >> (2 * level)) - (lo >> (2 * level)), ivec2(HIZ_SPAN - 1)))) ++level;
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
    dmat4 C = P.clip;
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
    return nearest <= double(farthest(lo_px, hi_px)) + 1.0lf / double(DEPTH_LEVELS);
}

void main() {
    EACH_UNIT
    uint bits = w[u];
    if ((bits & INF) == 0u) return;
    if ((bits & TESTED1) != 0u && passes(u)) {
        w[u] = bits | HIZ;                           // the box test against pass 1's depth decides
        w[LIST1_AT * n + atomicAdd(P.test1_cmd[1], 1u)] = u;
    }
}
