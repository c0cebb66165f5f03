// What both envelope passes share (core/gl/gpuenvelope.py; core/envelope.py is the
// reference, in numpy): the image's size, a pixel's tangent radius, and +inf.  Every
// value is computed as the reference computes it, in the same precision and order
// (double for depths, float for the rest), each result `precise` (no fused multiply-add).
uniform ivec2 u_size;          // (columns, rows) of the envelope's image
uniform double u_dt;           // tangent units per pixel
uniform double u_cx0;          // 0.5 * columns * dt
uniform double u_cy0;          // tan(half the vertical angle)
const float INF = uintBitsToFloat(0x7f800000u);

int at(ivec2 p) { return p.y * u_size.x + p.x; }
bool inside(ivec2 p) { return all(greaterThanEqual(p, ivec2(0))) && all(lessThan(p, u_size)); }

// the tangent-plane distance of a pixel's centre from the view axis, rounded to float
float tangent(ivec2 p) {
    precise double cx = (double(p.x) + 0.5LF) * u_dt - u_cx0;
    precise double cy = (double(p.y) + 0.5LF) * u_dt - u_cy0;
    precise double r2 = cx * cx + cy * cy;
    return float(sqrt(r2));
}
