// Entry t0 >= 0 and exit t1 of the unit box [0,1]^3 along the ray ro + t rd (slab test); false when
// the ray misses it. Direction components below 1e-12 in magnitude are replaced by 1e-12 so the
// test stays finite. Torch twin: models/unit_box.py (the volume marches' twins use it).
bool unit_box(vec3 ro, vec3 rd, out float t0, out float t1) {
    vec3 d = vec3(abs(rd.x) < 1e-12 ? 1e-12 : rd.x, abs(rd.y) < 1e-12 ? 1e-12 : rd.y,
                  abs(rd.z) < 1e-12 ? 1e-12 : rd.z);
    vec3 inv = 1.0 / d;
    vec3 a = (vec3(0.0) - ro) * inv;
    vec3 c = (vec3(1.0) - ro) * inv;
    vec3 lo = min(a, c);
    vec3 hi = max(a, c);
    t0 = max(max(lo.x, lo.y), max(lo.z, 0.0));
    t1 = min(hi.x, min(hi.y, hi.z));
    return t1 >= t0;
}
