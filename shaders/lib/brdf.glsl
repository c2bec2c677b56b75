// Analytic BRDFs; models/brdf.py is the torch twin (same operations in the same order).
// Local frame: normal +z, tangent +x (anisotropy axis), bitangent +y. v points to the camera
// (Li's w_in), l to the light (w_out). disney_brdf includes the cosine |n.l| as Li's does.

#define BRDF_PI 3.14159265
#define BRDF_INV_PI 0.318309886
#define BRDF_SUBSURFACE_NORM 0.397887358  // 1.25 / pi
#define BRDF_ALPHA_MIN 0.0001
#define BRDF_R0 0.04                       // ((1.5 - 1) / (1.5 + 1))^2
#define BRDF_CLEARCOAT_ALPHA 0.25

// Li's artist parameters (glass excluded), each in [0, 1]; base_color is linear RGB.
struct DisneyMaterial {
    vec3 base_color;
    float roughness, metallic, anisotropic, subsurface, specular, specular_tint,
          sheen, sheen_tint, clearcoat, clearcoat_gloss;
};

float brdf_pow5(float x) {
    float x2 = x * x;
    return x2 * x2 * x;
}

// The paper's isotropic GGX: D(h_z, a) = a^4 / (pi (1 + (a^4 - 1) h_z^2)^2).
float ggx(float nh, float alpha_h) {
    float a2 = alpha_h * alpha_h;
    float a4 = a2 * a2;
    float t = 1.0 + (a4 - 1.0) * (nh * nh);
    return a4 / (BRDF_PI * (t * t));
}

float brdf_luminance(vec3 c) {
    return c.x * 0.2126 + c.y * 0.7152 + c.z * 0.0722;
}

vec3 brdf_half_vector(vec3 l, vec3 v) {
    vec3 h = l + v;
    return h * inversesqrt(h.x * h.x + h.y * h.y + h.z * h.z);
}

float brdf_smith_g1(vec3 w, float ax, float ay) {
    float x = w.x * ax;
    float y = w.y * ay;
    float t = (x * x + y * y) / (w.z * w.z);
    float lam = (sqrt(1.0 + t) - 1.0) * 0.5;
    return 1.0 / (1.0 + lam);
}

vec3 disney_brdf(DisneyMaterial m, vec3 l, vec3 v) {
    if (l.z <= 0.0 || v.z <= 0.0) return vec3(0.0);
    float r = m.roughness;
    float ss = m.subsurface;
    vec3 h = brdf_half_vector(l, v);
    float nl = l.z, nv = v.z, nh = h.z;
    float hl = h.x * l.x + h.y * l.y + h.z * l.z;
    float fl = brdf_pow5(1.0 - nl), fv = brdf_pow5(1.0 - nv), s = brdf_pow5(1.0 - hl);
    float hl2 = hl * hl;
    // diffuse with subsurface (Li Eq. 3-5)
    float fd90 = 0.5 + 2.0 * r * hl2;
    float base = BRDF_INV_PI * (1.0 + (fd90 - 1.0) * fl) * (1.0 + (fd90 - 1.0) * fv) * nl;
    float fss90 = r * hl2;
    float fss = (1.0 + (fss90 - 1.0) * fl) * (1.0 + (fss90 - 1.0) * fv);
    float sub = BRDF_SUBSURFACE_NORM * (fss * (1.0 / (nl + nv) - 0.5) + 0.5) * nl;
    float fd = (1.0 - ss) * base + ss * sub;
    // metal: anisotropic GGX + Smith (Li Eq. 6-10)
    float aspect = sqrt(1.0 - 0.9 * m.anisotropic);
    float r2 = r * r;
    float ax = max(r2 / aspect, BRDF_ALPHA_MIN), ay = max(r2 * aspect, BRDF_ALPHA_MIN);
    float hx = h.x / ax, hy = h.y / ay;
    float q = hx * hx + hy * hy + nh * nh;
    float d = 1.0 / (BRDF_PI * ax * ay * (q * q));
    float metal = d * brdf_smith_g1(l, ax, ay) * brdf_smith_g1(v, ax, ay) / (4.0 * nv);
    // clearcoat (Li Eq. 11-13)
    float g = m.clearcoat_gloss;
    float ag = (1.0 - g) * 0.1 + g * 0.001;
    float ag2 = ag * ag;
    float dc = (ag2 - 1.0) / (BRDF_PI * log(ag2) * (1.0 + (ag2 - 1.0) * (nh * nh)));
    float fc = BRDF_R0 + 0.96 * s;
    float clear = fc * dc * brdf_smith_g1(l, BRDF_CLEARCOAT_ALPHA, BRDF_CLEARCOAT_ALPHA)
                * brdf_smith_g1(v, BRDF_CLEARCOAT_ALPHA, BRDF_CLEARCOAT_ALPHA) / (4.0 * nv);
    // combination (Li Eq. 19 without glass)
    float lum = brdf_luminance(m.base_color);
    vec3 tint = lum > 0.0 ? m.base_color / max(lum, 1e-30) : vec3(1.0);
    vec3 ks = (1.0 - m.specular_tint) + m.specular_tint * tint;
    vec3 c0 = m.specular * BRDF_R0 * (1.0 - m.metallic) * ks + m.metallic * m.base_color;
    vec3 fm = c0 + (1.0 - c0) * s;
    vec3 csheen = (1.0 - m.sheen_tint) + m.sheen_tint * tint;
    return (1.0 - m.metallic) * m.base_color * fd
         + (1.0 - m.metallic) * m.sheen * csheen * (s * nl)
         + fm * metal
         + 0.25 * m.clearcoat * clear;
}
