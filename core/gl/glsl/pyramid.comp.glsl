// Levels 1 and 2 of the max-depth pyramid in one dispatch (each texel the FARTHEST depth
// of the pixels it covers: conservative), one thread per level-2 texel (16 x 16 pixels),
// no barriers.  textureGather at a texel corner reads the 2 x 2 pixels around it; at the
// image's right or top edge it wraps to pixels of the other side: a larger maximum,
// conservative.
#include "layout/gpucull.glsl"
uniform sampler2D u_depth;
layout(local_size_x = 8, local_size_y = 8) in;
void main() {
    ivec2 size = textureSize(u_depth, 0);
    ivec2 s1z = (size + 3) / 4, s2z = (s1z + 3) / 4;
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (t.x >= s2z.x || t.y >= s2z.y) return;
    vec2 texel = 1.0 / vec2(size);
    float m2 = 0.0;
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            ivec2 l1 = 4 * t + ivec2(i, j);
            if (l1.x >= s1z.x || l1.y >= s1z.y) continue;
            float m = 0.0;
            for (int b = 1; b < 4; b += 2)
                for (int a = 1; a < 4; a += 2) {
                    vec4 g = textureGather(u_depth, vec2(4 * l1 + ivec2(a, b)) * texel);
                    m = max(m, max(max(g.x, g.y), max(g.z, g.w)));
                }
            z[l1.y * s1z.x + l1.x] = m;
            m2 = max(m2, m);
        }
    z[s1z.x * s1z.y + t.y * s2z.x + t.x] = m2;
}
