// Each unit's state and the memory of the next pass.
#include "cull_unit.glsl"
void main() {
    EACH_UNIT
    uint bits = w[u] & ~(STATE | PREV);
    if ((bits & INF) == 0u) { w[u] = bits | STATE_VIEW_CULLED; return; }
    // VISIBLE: near (by rule) or its box passed the test against the completed depth;
    // OCCLUDED: its box failed a test against real geometry (test 1 or test 2)
    bool visible = (bits & NEAR) != 0u || ((bits & TESTED2) != 0u && w[FLAG2_AT * n + u] != 0u);
    w[u] = bits | (visible ? PREV : STATE_OCCLUDED);
}
