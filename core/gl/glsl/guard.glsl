// core.cull.view_pass.CullPass.guard, per axis: relative + pixel guard across the rays +
// depth steps along them (its parameters from the Params block, written by name by
// GpuCull.params; tests/test_gl_layout.py runs both on the same boxes).  After
// cull_unit.glsl (maxabs, P).
dvec3 guard(dvec3 lo, dvec3 hi) {
    double mag = max(maxabs(lo), maxabs(hi));
    dvec3 e = hi - lo;
    double base = P.grow_rel * (mag + max(e.x, max(e.y, e.z))) + P.grow_abs;
    dvec3 vmin, vmax;
    double lateral, tie;
    if (P.perspective > 0.5) {
        // farthest and nearest eye-space depth: w of the corners farthest and nearest
        // along the w row (row 3 of the column-major clip)
        dvec3 wrow = dvec3(P.clip[0][3], P.clip[1][3], P.clip[2][3]);
        double w3 = P.clip[3][3];
        bvec3 pos = greaterThanEqual(wrow, dvec3(0.0));
        double far_w = max(dot(mix(lo, hi, pos), wrow) + w3, 0.0);
        double near_w = dot(mix(hi, lo, pos), wrow) + w3;
        lateral = P.lateral * far_w;
        bvec3 spans = bvec3(lo.x <= 0.0 && hi.x >= 0.0, lo.y <= 0.0 && hi.y >= 0.0, lo.z <= 0.0 && hi.z >= 0.0);
        dvec3 near_abs = mix(min(abs(lo), abs(hi)), dvec3(0.0), spans);
        dvec3 far_abs = max(abs(lo), abs(hi));
        double far_norm = sqrt(dot(far_abs, far_abs));
        double near_norm = sqrt(dot(near_abs, near_abs));
        vmin = near_abs / max(far_norm, P.tiny);
        vmax = min(far_abs / max(near_norm, P.tiny), dvec3(1.0));
        tie = P.tie * far_w * far_w * far_norm / max(near_w, P.tiny + GUARD_NEAR_W_REL * far_norm);
    } else {
        lateral = P.lateral;
        vmin = vmax = P.dir;
        tie = P.tie;
    }
    dvec3 across = sqrt(max(dvec3(1.0) - vmin * vmin, dvec3(0.0)));
    return dvec3(base) + lateral * across + tie * vmax;
}
