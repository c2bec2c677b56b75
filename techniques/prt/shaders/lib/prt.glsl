// Precomputed radiance transfer with a learnt transfer network (Learnt Transfer, Dhawal et al. 2022).
// A transfer vector t (16 SH coefficients of V(w) max(0, w.n), four vec4 blocks) comes from the
// network at (p, n); the environment is radiance SH u_sh (codegen/sdf.py environment_sh).
//   diffuse: albedo / pi * sum_k t_k L_k                       (per channel)
//   glossy:  sum_k g_l(k) H_k y_k(R), H_c = M_c t              (M_c: u_prt_light, per lighting)
// with g_l the normalised Phong lobe's band factors for exponent s (inshade.sh.phong_bands) and
// R the reflection direction. Final = kd * diffuse [+ ks * glossy]. Torch twins, same order:
// techniques/prt/twin.py (prt_transfer, prt_diffuse, prt_glossy, prt_shade).
// <prt_network> (techniques/prt/codegen.py) includes the transfer network and defines PRT_NET_EVAL,
// PRT_CENTER, PRT_INV_RADIUS and PRT_SCALE. The u_shading values PRT_DIFFUSE, PRT_GLOSSY are the
// programs' choices (SHADING_MODES in techniques/prt/__init__.py), generated into <choices>.
#include <lib/spherical_harmonics>
#include <prt_network>
#include <choices>

#if SH_COEFFS != 16
#error "lib/prt needs a degree-4 environment (16 SH coefficients, the transfer contract)"
#endif
#define PRT_BLOCKS 4
#define PRT_DEBUG_POSITION 5  // u_prt_debug: 1..4 transfer block, 5 position, 6 normal
#define PRT_DEBUG_NORMAL 6

// M_c in 4x4 blocks: u_prt_light[c * 16 + 4 * bk + bi] = rows 4bk.., columns 4bi.. of M_c
// (techniques/prt/codegen.py light_matrix_uniform; recomputed on the CPU when the lighting changes).
uniform mat4 u_prt_light[3 * PRT_BLOCKS * PRT_BLOCKS];

const float PRT_INV_PI = 0.318309873;  // float32(1 / pi), as techniques/prt/twin.py INV_PI

// The network's transfer at p with unit normal n: position normalised to the bound's unit ball,
// output times the bundle's scale (techniques/prt/transfer_model.py evaluate_transfer).
void prt_transfer(vec3 p, vec3 n, out vec4 t[PRT_BLOCKS]) {
    vec3 q = (p - PRT_CENTER) * PRT_INV_RADIUS;
    vec4 x[PRT_NET_IN_BLOCKS];
    x[0] = vec4(q, n.x);
    x[1] = vec4(n.y, n.z, 0.0, 0.0);
    vec4 y[PRT_NET_OUT_BLOCKS];
    PRT_NET_EVAL(x, y);
    for (int b = 0; b < PRT_BLOCKS; ++b) {
        t[b] = y[b] * PRT_SCALE;
    }
}

// sum_k t_k L_k, accumulated in index order.
vec3 prt_diffuse(in vec4 t[PRT_BLOCKS], in vec3 coeffs[SH_COEFFS]) {
    vec3 acc = vec3(0.0);
    for (int i = 0; i < SH_COEFFS; ++i) {
        acc = acc + coeffs[i] * t[i / 4][i % 4];
    }
    return acc;
}

// Band factors of the normalised Phong lobe (s + 1) / (2 pi) max(cos a, 0)^s: (s + 1) M_l with
// M_0 = 1 / (s + 1), M_1 = 1 / (s + 2), M_l = (s - l + 2) / (s + l + 1) M_{l-2} (inshade.sh).
void prt_phong_bands(float s, out float g[SH_DEGREE]) {
    float m[SH_DEGREE];
    for (int l = 0; l < SH_DEGREE; ++l) {
        float fl = float(l);
        m[l] = l < 2 ? 1.0 / (s + 1.0 + fl) : (s - fl + 2.0) / (s + fl + 1.0) * m[l < 2 ? 0 : l - 2];
        g[l] = (s + 1.0) * m[l];
    }
}

// Glossy radiance towards the viewer: the product (lighting x transfer) projected (H_c = M_c t),
// convolved with the Phong lobe and evaluated at the reflection direction r.
vec3 prt_glossy(in vec4 t[PRT_BLOCKS], vec3 r, float exponent) {
    float g[SH_DEGREE];
    prt_phong_bands(exponent, g);
    float y[SH_COEFFS];
    sh_basis(r, y);
    vec4 w[PRT_BLOCKS];  // g_l(k) y_k(r), four lanes per block
    for (int b = 0; b < PRT_BLOCKS; ++b) {
        w[b] = vec4(g[SH_BAND[4 * b]] * y[4 * b], g[SH_BAND[4 * b + 1]] * y[4 * b + 1],
                    g[SH_BAND[4 * b + 2]] * y[4 * b + 2], g[SH_BAND[4 * b + 3]] * y[4 * b + 3]);
    }
    vec3 out_c = vec3(0.0);
    for (int c = 0; c < 3; ++c) {
        float acc = 0.0;
        for (int bk = 0; bk < PRT_BLOCKS; ++bk) {
            int base = c * 16 + 4 * bk;
            vec4 h = u_prt_light[base] * t[0] + u_prt_light[base + 1] * t[1] + u_prt_light[base + 2] * t[2]
                     + u_prt_light[base + 3] * t[3];
            acc = acc + dot(h, w[bk]);
        }
        out_c[c] = acc;
    }
    return out_c;
}

// Outgoing radiance at a surface point: albedo (already tinted), normal n, view ray direction rd.
vec3 prt_shade(in vec4 t[PRT_BLOCKS], vec3 albedo, vec3 n, vec3 rd, in vec3 coeffs[SH_COEFFS], int shading,
               float exponent, float kd, float ks) {
    vec3 c = albedo * prt_diffuse(t, coeffs) * PRT_INV_PI * kd;
    if (shading == PRT_GLOSSY) {
        c = c + prt_glossy(t, reflect(rd, n), exponent) * ks;
    }
    return c;
}

// What a debug view shows at a covered pixel (see PRT_DEBUG_*).
vec4 prt_debug(int mode, in vec4 t[PRT_BLOCKS], vec3 p, vec3 n) {
    if (mode == PRT_DEBUG_POSITION) {
        return vec4(p, 1.0);
    }
    if (mode == PRT_DEBUG_NORMAL) {
        return vec4(n, 1.0);
    }
    return t[clamp(mode - 1, 0, PRT_BLOCKS - 1)];
}
