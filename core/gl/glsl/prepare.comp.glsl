// Pass step 1 (core/gl/gpucull.py): the frustum test, the guard, the near-plane rule;
// last pass's visible and the near units go to pass 1, the others to test 1.
#include "cull_unit.glsl"
#include "guard.glsl"

void main() {
    EACH_UNIT
    uint prev = w[u] & PREV;
    w[FLAG1_AT * n + u] = 0u;
    w[FLAG2_AT * n + u] = 0u;
    c[5u * u + 1u] = 0u;
    c[5u * (n + u) + 1u] = 0u;
    Unit un = units[u];
    if (un.lo.w == 0.0) { w[u] = STATE_VIEW_CULLED; return; }      // invalid: never drawn, never tested
    dvec3 eye = P.eye;
    dvec3 lo = un.lo.xyz - eye, hi = un.hi.xyz - eye;
    double scale = max(maxabs(lo), maxabs(hi));
    for (int k = 0; k < 6; ++k) {
        dvec4 p = P.planes[k];
        // outside only beyond the plane tolerance (classify_fast's rule)
        double dp = dot(max(p.xyz, dvec3(0.0)), hi) + dot(min(p.xyz, dvec3(0.0)), lo) + p.w;
        if (dp < -P.plane_rel * (scale + abs(p.w))) { w[u] = STATE_VIEW_CULLED; return; }
    }
    dvec3 g = guard(lo, hi);
    dvec3 glo = lo - g, ghi = hi + g;
    // Conservative: a grown box that reaches the near plane is visible without a test
    dvec4 np = P.planes[4];
    bvec3 npos = greaterThanEqual(np.xyz, dvec3(0.0));
    double lowest = dot(mix(ghi, glo, npos), np.xyz) + np.w;
    bool near = lowest <= P.near_rel * max(maxabs(glo), maxabs(ghi));
    dyn[u].glo = vec4(clamp(glo, dvec3(-P.extent), dvec3(P.extent)), 0.0);
    dyn[u].ghi = vec4(clamp(ghi, dvec3(-P.extent), dvec3(P.extent)), 0.0);
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
