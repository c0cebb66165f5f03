// The box test: list LIST's boxes (a define given at compile time), one instance each,
// corners from gl_VertexID (as the renderer's box_43.vert.glsl), front faces only, early
// depth test <=, no depth write.
#include "layout/gpucull.glsl"
#include "layout/box.glsl"
flat out uint v_unit;
const int CORNER[36] = int[36](BOX_CORNERS);
void main() {
    uint u = w[LIST * P.n_units + uint(gl_InstanceID)];
    v_unit = u;
    vec4 lo = dyn[u].glo, hi = dyn[u].ghi;
    int k = CORNER[gl_VertexID];
    vec3 p = vec3((k & 1) != 0 ? hi.x : lo.x, (k & 2) != 0 ? hi.y : lo.y, (k & 4) != 0 ? hi.z : lo.z);
    gl_Position = P.vp * vec4(p, 1.0);
}
