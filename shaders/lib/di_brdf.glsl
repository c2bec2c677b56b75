// Learned Disney BRDF glue (Differentiable Indirection, Datta et al. 2023 supp. 1.2); the torch twin is
// models/disney_glue.py `disney_glue` (same operations, same order). The five runtime lookups
// (decoders) arrive already evaluated in DiDisney; this is the arithmetic that combines them:
//   Disney(x, A) = (A / lum(A)) p + q                                        (paper Eq. 3)
//   p = c_d lum f_d + c_s st S nl + (c_d k_m0 + c_m lum)(1 - S) D_m G_m
//   q = c_s (1 - st) S nl + (c_d k_m1 (1 - S) + S) D_m G_m + k_c F_c D_c G_c
// D_m = 1 / (d0 hx^2 + d1 hy^2 + d2 nh^2)^2 (the learned "denominator", 3 ch), G_m Schlick-Smith
// with the learned k (1 ch), f_d = nl sum_i f_i g_i with learned f_i (4 ch) and analytic g_i,
// (c_d, c_m, c_s, k_cc) = (1 - metallic, metallic, (1 - metallic) sheen, clearcoat k) (4 ch),
// D_c = 1 / (e0 (1 - nh^2) + e1) from the 1D clearcoat-gloss lookup (2 ch).
// Directions in the local frame (normal +z, tangent +x); the cosine |n.l| is included.

struct DiDisney {
    vec3 ggx;      // d0, d1, d2
    float smith;   // k
    vec4 diff;     // f_0..f_3
    vec4 coef;     // c_d, c_m, c_s, k_cc
    vec2 gloss;    // e0, e1
    float sheen_tint;
    vec3 k;        // 0.04 specular specular_tint, 0.04 specular (1 - specular_tint), clearcoat / 4
    vec3 albedo;
};

float di_pow5(float x) {
    float x2 = x * x;
    return x2 * x2 * x;
}

vec3 di_disney_brdf(DiDisney d, vec3 l, vec3 v) {
    if (l.z <= 0.0 || v.z <= 0.0) return vec3(0.0);
    vec3 h = l + v;
    h = h * inversesqrt(h.x * h.x + h.y * h.y + h.z * h.z);
    float nl = l.z, nv = v.z, nh = h.z;
    float hl = h.x * l.x + h.y * l.y + h.z * l.z;
    float fl = di_pow5(1.0 - nl), fv = di_pow5(1.0 - nv), s = di_pow5(1.0 - hl);
    float t = hl * hl;
    float flv = fl * fv;
    float w = 1.0 / (nl + nv) - 0.5;
    float fd = nl * (d.diff.x * ((1.0 - 0.5 * fl) * (1.0 - 0.5 * fv)) + d.diff.y * (2.0 * t * (fl + fv - flv))
                     + d.diff.z * ((1.0 - fl) * (1.0 - fv) * w + 0.5) + d.diff.w * (t * (fl + fv - 2.0 * flv) * w));
    float den = d.ggx.x * (h.x * h.x) + d.ggx.y * (h.y * h.y) + d.ggx.z * (nh * nh);
    float k = d.smith;
    float dg = 1.0 / (den * den) * (nl / (nl * (1.0 - k) + k)) * (1.0 / (4.0 * (nv * (1.0 - k) + k)));
    float kc = d.coef.w;
    float gc = (nl / (nl * (1.0 - kc) + kc)) * (1.0 / (4.0 * (nv * (1.0 - kc) + kc)));
    float dc = 1.0 / (d.gloss.x * (1.0 - nh * nh) + d.gloss.y);
    float fc = 0.04 + 0.96 * s;
    float lum = max(d.albedo.x * 0.2126 + d.albedo.y * 0.7152 + d.albedo.z * 0.0722, 0.0001);
    float sn = s * nl;
    float p = d.coef.x * lum * fd + d.coef.z * d.sheen_tint * sn + (d.coef.x * d.k.x + d.coef.y * lum) * (1.0 - s) * dg;
    float q = (d.coef.z - d.coef.z * d.sheen_tint) * sn + (d.coef.x * d.k.y * (1.0 - s) + s) * dg + d.k.z * fc * dc * gc;
    return d.albedo / lum * p + q;
}
