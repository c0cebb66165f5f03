// 4.3: one instance per query box; the 36 corners come from the box's lo/hi by
// gl_VertexID, so a batch is one draw whatever its size.
#include "layout/box.glsl"
in vec3 in_lo;
in vec3 in_hi;
uniform mat4 u_vp;
flat out int v_box;
const int CORNER[36] = int[36](BOX_CORNERS);
void main() {
    int c = CORNER[gl_VertexID];
    // a corner takes each coordinate from lo or hi exactly (no arithmetic on it)
    vec3 p = vec3((c & 1) != 0 ? in_hi.x : in_lo.x,
                  (c & 2) != 0 ? in_hi.y : in_lo.y,
                  (c & 4) != 0 ? in_hi.z : in_lo.z);
    gl_Position = u_vp * vec4(p, 1.0);
    v_box = gl_InstanceID;
}
