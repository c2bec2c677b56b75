// The volume march of a field network (torch twin: march.py beside passes/imported_field.frag, same
// steps, same order, float32; WGSL twin field_march.wgsl). The network (net_eval) maps (position, direction)
// (6 lanes) to rgb and density (4); <field_config> holds the march's settings (codegen/field.py).
//
// Per pixel: the box FIELD_BOX_LO..FIELD_BOX_HI entry t0 >= 0 / exit t1 (slab test; direction
// components below 1e-12 in magnitude replaced by 1e-12); for i = 0 .. FIELD_MAX_STEPS - 1:
// t = t0 + (i + 0.5) FIELD_STEP, stop when t >= t1; sigma = max(density, 0); alpha = 1 -
// exp(-sigma FIELD_STEP); C += T alpha rgb; T *= 1 - alpha; stop once T < FIELD_STOP.
// field_march: C + T FIELD_BACKGROUND, alpha 1; field_march_parts: C, returning T (what a caller
// compositing over a scene of its own needs).
#if !defined(FIELD_BOX_LO) || !defined(FIELD_STEP) || !defined(FIELD_MAX_STEPS) || !defined(FIELD_BACKGROUND)
#error "lib/field_march needs <field_config> (codegen/field.py: render.field of the bundle)"
#endif
#if NET_IN_DIM != 6 || NET_OUT_DIM != 4
#error "lib/field_march needs a network mapping position + direction (6 lanes) to rgb + density (4 lanes)"
#endif

bool field_box(vec3 ro, vec3 rd, out float t0, out float t1) {
    vec3 d = vec3(abs(rd.x) < 1e-12 ? 1e-12 : rd.x, abs(rd.y) < 1e-12 ? 1e-12 : rd.y,
                  abs(rd.z) < 1e-12 ? 1e-12 : rd.z);
    vec3 inv = 1.0 / d;
    vec3 a = (FIELD_BOX_LO - ro) * inv;
    vec3 c = (FIELD_BOX_HI - ro) * inv;
    vec3 lo = min(a, c);
    vec3 hi = max(a, c);
    t0 = max(max(lo.x, lo.y), max(lo.z, 0.0));
    t1 = min(hi.x, min(hi.y, hi.z));
    return t1 >= t0;
}

float field_march_parts(vec3 ro, vec3 rd, out vec3 colour) {
    colour = vec3(0.0);
    float trans = 1.0;
    float t0, t1;
    if (!field_box(ro, rd, t0, t1)) return trans;
    for (int i = 0; i < FIELD_MAX_STEPS; ++i) {
        float t = t0 + (float(i) + 0.5) * FIELD_STEP;
        if (t >= t1) break;
        vec3 p = ro + rd * t;
        vec4 x[NET_IN_BLOCKS];
        x[0] = vec4(p, rd.x);
        x[1] = vec4(rd.yz, 0.0, 0.0);
        vec4 y[NET_OUT_BLOCKS];
        net_eval(x, y);
        float sigma = max(y[0].w, 0.0);
        float alpha = 1.0 - exp(-sigma * FIELD_STEP);
        colour += (trans * alpha) * y[0].rgb;
        trans = trans * (1.0 - alpha);
        if (trans < FIELD_STOP) break;
    }
    return trans;
}

vec4 field_march(vec3 ro, vec3 rd) {
    vec3 colour;
    float trans = field_march_parts(ro, rd, colour);
    return vec4(colour + trans * FIELD_BACKGROUND, 1.0);
}
