// Each fragment that passes the depth test sets its unit's flag in array FLAG (a define
// given at compile time).
#include "layout/gpucull.glsl"
layout(early_fragment_tests) in;
flat in uint v_unit;
void main() { w[FLAG * P.n_units + v_unit] = 1u; }
