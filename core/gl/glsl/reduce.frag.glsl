// Conservative depth reduction (display -> query resolution): each query pixel takes
// the FARTHEST depth of every display pixel its area overlaps, so a gap open at display
// resolution stays open at query resolution.  Both depth buffers are 24-bit and a value
// read and written back goes through float (llvmpipe rounds it 0 or 1 step farther; a
// driver may round nearer), so one step is added: conservative, the reduced depth is
// never nearer than the display's.
#include "layout/depth.glsl"
const float DEPTH_STEP = 1.0 / DEPTH_LEVELS;
uniform sampler2D u_depth;
uniform ivec2 u_display;
uniform ivec2 u_query;
void main() {
    ivec2 q = ivec2(gl_FragCoord.xy);
    ivec2 lo = (q * u_display) / u_query;
    ivec2 hi = ((q + 1) * u_display + u_query - 1) / u_query;     // exclusive
    float d = 0.0;
    for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x)
            d = max(d, texelFetch(u_depth, ivec2(x, y), 0).r);
    gl_FragDepth = min(d + DEPTH_STEP, 1.0);
}
