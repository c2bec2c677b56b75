// The radiance-field volume march (torch twin: techniques/di_radiance_field/march.py, same steps,
// same order, float32). Networks <network_rfg> (the uncompressed grids) and <network_rfd> (the DI
// cascades) both map x in [0,1]^3 to 13 lanes: colour SH logits (12, coefficient-major: lane 3k + c
// is coefficient k of RGB channel c) then sigma (1).
//
// Per pixel: unit box entry t0 >= 0 / exit t1 (slab test, |rd| components below 1e-12 replaced);
// y_k = SH basis (degree 1, 4 values) of rd; for i = 0 .. RF_MAX_STEPS - 1: t = t0 + (i + 0.5) dt,
// stop when t >= t1; sigma = max(s - RF_DENSITY_FLOOR, 0) RF_SIGMA_SCALE; alpha = 1 - exp(-sigma dt);
// rgb = sigmoid(sum_k y_k c_k); C += T alpha rgb; T *= 1 - alpha; stop once T < RF_STOP.
// Result: C + T background, alpha 1 (the constant background is part of the image).
// <rf_config> (the record's chunk) defines RF_STEP (dt), RF_MAX_STEPS, RF_STOP, RF_BACKGROUND,
// RF_SIGMA_SCALE (the networks' density lane is sigma / RF_SIGMA_SCALE: unit scale) and RF_DENSITY_FLOOR
// (density below it is empty space: DVGO-like low-density threshold).
#include <lib/spherical_harmonics>
#include <lib/unit_box>

#if !defined(RF_STEP) || !defined(RF_MAX_STEPS) || !defined(RF_STOP) || !defined(RF_BACKGROUND) || !defined(RF_SIGMA_SCALE) || !defined(RF_DENSITY_FLOOR)
#error "lib/rf_march needs RF_STEP, RF_MAX_STEPS, RF_STOP, RF_BACKGROUND, RF_SIGMA_SCALE and RF_DENSITY_FLOOR (the record's <rf_config>)"
#endif
#if RFG_OUT_DIM != 13 || RFD_OUT_DIM != 13 || RFG_IN_DIM != 3 || RFD_IN_DIM != 3
#error "lib/rf_march needs networks 'rfg' and 'rfd' mapping x[3] to colour[12] + density[1]"
#endif


// which: 0 = the uncompressed grids (rfg), 1 = the DI cascades (rfd)
void rf_sample(int which, vec3 x, out vec4 y[4]) {
    vec4 xin[1];
    xin[0] = vec4(x, 0.0);
    if (which == 0) {
        rfg_eval(xin, y);
    } else {
        rfd_eval(xin, y);
    }
}

vec4 rf_march(int which, vec3 ro, vec3 rd) {
    float t0, t1;
    if (!unit_box(ro, rd, t0, t1)) return vec4(RF_BACKGROUND, 1.0);
    float ys[SH_COEFFS];
    sh_basis(rd, ys);
    float dt = RF_STEP;
    vec3 colour = vec3(0.0);
    float trans = 1.0;
    for (int i = 0; i < RF_MAX_STEPS; ++i) {
        float t = t0 + (float(i) + 0.5) * dt;
        if (t >= t1) break;
        vec4 y[4];
        rf_sample(which, ro + rd * t, y);
        vec3 c0 = y[0].xyz;
        vec3 c1 = vec3(y[0].w, y[1].xy);
        vec3 c2 = vec3(y[1].zw, y[2].x);
        vec3 c3 = y[2].yzw;
        float sigma = max(y[3].x - RF_DENSITY_FLOOR, 0.0) * RF_SIGMA_SCALE;
        vec3 z = ys[0] * c0 + ys[1] * c1 + ys[2] * c2 + ys[3] * c3;
        vec3 rgb = 1.0 / (1.0 + exp(-z));
        float alpha = 1.0 - exp(-sigma * dt);
        colour += (trans * alpha) * rgb;
        trans = trans * (1.0 - alpha);
        if (trans < RF_STOP) break;
    }
    return vec4(colour + trans * RF_BACKGROUND, 1.0);
}
