// The hash-grid radiance field's march (torch twin: techniques/hash_grid/radiance_field_march.py,
// same steps, same order, float32). Network <network_hgrf>: x[3] (box, [0,1]^3), d[3] (unit ray
// direction) -> density[1], rgb[3]; network <network_hgocc>: x[3] -> occupancy[1], a G^3 lookup
// array whose node c is the bit of cell c (read on the node, x = c / (G - 1), tested > 0.5).
//
// Per ray, in box units (ro = (eye - HGRF_AABB_MIN) * HGRF_INV_SIDE): box entry t0 >= 0 / exit t1;
// i = 0; for n < HGRF_MAX_STEPS: stop when i >= HGRF_MAX_STEPS; t = t0 + (i + 0.5) dt, stop when
// t >= t1; x = ro + rd t; when skipping and x's cell is empty: i = max(i + 1, floor((t_exit - t0) / dt
// - 0.5)) (the last sample before the cell's exit; the landing sample is tested again), next;
// alpha = 1 - exp(-density HGRF_SIGMA_SCALE dt); C += T alpha rgb; T *= 1 - alpha; i += 1; stop once
// T < HGRF_STOP. Result: C + T background. <radiance_field_config> (the record's chunk) defines the
// HGRF_* settings from the field bundle's render metadata.
#include <lib/unit_box>

#if !defined(HGRF_STEP) || !defined(HGRF_MAX_STEPS) || !defined(HGRF_STOP) || !defined(HGRF_BACKGROUND) || !defined(HGRF_SIGMA_SCALE) || !defined(HGRF_OCCUPANCY_RES) || !defined(HGRF_AABB_MIN) || !defined(HGRF_INV_SIDE)
#error "lib/radiance_field_march needs the HGRF_* settings (the record's <radiance_field_config>)"
#endif
#if HGRF_IN_DIM != 6 || HGRF_OUT_DIM != 4 || HGOCC_IN_DIM != 3 || HGOCC_OUT_DIM != 1
#error "lib/radiance_field_march needs networks 'hgrf' (x[3], d[3] -> density[1], rgb[3]) and 'hgocc' (x[3] -> occupancy[1])"
#endif

const float HGRF_CELL = 1.0 / float(HGRF_OCCUPANCY_RES);
const float HGRF_NODE = 1.0 / float(HGRF_OCCUPANCY_RES - 1);
const float HGRF_INV_STEP = 1.0 / HGRF_STEP;

bool hgrf_occupied(ivec3 cell) {
    vec4 xin[1];
    xin[0] = vec4(vec3(cell) * HGRF_NODE, 0.0);
    vec4 y[1];
    hgocc_eval(xin, y);
    return y[0].x > 0.5;
}

// t where the ray leaves the cell (its far slabs), the reciprocal as lib/unit_box takes it
float hgrf_cell_exit(vec3 ro, vec3 rd, ivec3 cell) {
    vec3 lo = vec3(cell) * HGRF_CELL;
    vec3 hi = vec3(cell + 1) * HGRF_CELL;
    vec3 d = vec3(abs(rd.x) < 1e-12 ? 1e-12 : rd.x, abs(rd.y) < 1e-12 ? 1e-12 : rd.y,
                  abs(rd.z) < 1e-12 ? 1e-12 : rd.z);
    vec3 inv = 1.0 / d;
    vec3 far = max((lo - ro) * inv, (hi - ro) * inv);
    return min(far.x, min(far.y, far.z));
}

// eye, rd in world units; skip: step over unoccupied cells; evals: network evaluations made
vec3 hgrf_march(vec3 eye, vec3 rd, bool skip, out int evals) {
    evals = 0;
    vec3 ro = (eye - HGRF_AABB_MIN) * HGRF_INV_SIDE;
    float t0, t1;
    if (!unit_box(ro, rd, t0, t1)) return HGRF_BACKGROUND;
    float dt = HGRF_STEP;
    vec3 colour = vec3(0.0);
    float trans = 1.0;
    int i = 0;
    for (int n = 0; n < HGRF_MAX_STEPS; ++n) {
        if (i >= HGRF_MAX_STEPS) break;
        float t = t0 + (float(i) + 0.5) * dt;
        if (t >= t1) break;
        vec3 x = ro + rd * t;
        if (skip) {
            ivec3 cell = clamp(ivec3(floor(x * float(HGRF_OCCUPANCY_RES))), ivec3(0), ivec3(HGRF_OCCUPANCY_RES - 1));
            if (!hgrf_occupied(cell)) {
                float t_exit = hgrf_cell_exit(ro, rd, cell);
                i = max(i + 1, int(floor((t_exit - t0) * HGRF_INV_STEP - 0.5)));
                continue;
            }
        }
        vec4 xin[2];
        xin[0] = vec4(x, rd.x);
        xin[1] = vec4(rd.yz, 0.0, 0.0);
        vec4 y[1];
        hgrf_eval(xin, y);
        evals += 1;
        float alpha = 1.0 - exp(-(y[0].x * HGRF_SIGMA_SCALE) * dt);
        colour += (trans * alpha) * y[0].yzw;
        trans = trans * (1.0 - alpha);
        i += 1;
        if (trans < HGRF_STOP) break;
    }
    return colour + trans * HGRF_BACKGROUND;
}
