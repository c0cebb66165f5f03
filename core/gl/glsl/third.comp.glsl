// Units whose box passed both tests against pass 1's depth are drawn in pass 2; every
// unit drawn and not near joins the list of test 2.
#include "cull_unit.glsl"
void main() {
    EACH_UNIT
    uint bits = w[u];
    if ((bits & INF) == 0u) return;
    if ((bits & HIZ) != 0u && w[FLAG1_AT * n + u] != 0u) {
        bits |= DRAWN2;
        c[5u * (n + u) + 1u] = 1u;
        set_mvp(u);
    }
    if ((bits & (DRAWN1 | DRAWN2)) != 0u && (bits & NEAR) == 0u) {
        bits |= TESTED2;
        w[LIST2_AT * n + atomicAdd(P.test2_cmd[1], 1u)] = u;
    }
    w[u] = bits;
}
