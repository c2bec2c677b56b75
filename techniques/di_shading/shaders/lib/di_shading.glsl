// End-to-end DI shading pipeline (Differentiable Indirection, Datta et al. 2023 §4.3.3): a PBR set
// sample (PbrSample below, from the DI footprint sampler or from the uncompressed set) on
// the ground plane y = 0, shaded by one point light + an ambient term, with the learned DI Disney
// BRDF (the frozen decoder bundle <network_brdf> + lib/di_brdf's glue) or the analytic one
// (lib/brdf). Torch twins: techniques/di_shading/model.py (plane_geometry, visible_normal, local_frame,
// shade_di, shade_analytic), same operations in the same order.
// Tangent space of the plane: x = +u = world +x, y = +v = world -z, z = the normal = world +y.
// The set's constant Disney parameters: metallic 0, anisotropic 0, subsurface 0, specular 0.5,
// specular_tint 0, sheen 0, sheen_tint 0.5, clearcoat 0, clearcoat_gloss 1 (model.py CONSTANTS).
#include <network_brdf>
#include <lib/colour>
#include <lib/brdf>
#include <lib/di_brdf>
#include <lib/pbr_sample>   // one sample of the 8-lane set: PbrSample, pbr_set_unpack

struct DiShadingGeometry {
    vec3 l;     // to the light, plane tangent space
    vec3 v;     // to the eye, plane tangent space
    float e;    // light intensity / distance^2
};

DiShadingGeometry di_shading_geometry(vec3 p, vec3 eye, vec3 light, float intensity) {
    DiShadingGeometry g;
    vec3 d = light - p;
    float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    vec3 lw = d * inversesqrt(d2);
    vec3 vw = eye - p;
    vw = vw * inversesqrt(vw.x * vw.x + vw.y * vw.y + vw.z * vw.z);
    g.l = vec3(lw.x, -lw.z, lw.y);
    g.v = vec3(vw.x, -vw.z, vw.y);
    g.e = intensity / d2;
    return g;
}

// Frame around the tangent-space normal n, tangent from +u (Gram-Schmidt); w -> (w.t, w.b, w.n).
void di_shading_frame(vec3 n, out vec3 t, out vec3 b) {
    t = vec3(1.0, 0.0, 0.0) - n * n.x;
    t = t * inversesqrt(max(t.x * t.x + t.y * t.y + t.z * t.z, 1e-30));
    b = cross(n, t);
}

// A set normal that faces away from the eye (a bumpy sample seen at grazing angles) would shade
// as its unlit back, a black speckle the filtered reference never shows; it is bent toward the
// eye until n.v = DI_SHADING_MIN_NV before normalising, as renderers do with normal maps.
#define DI_SHADING_MIN_NV 0.05
vec3 di_shading_visible_normal(vec3 n, vec3 v) {
    float nv = n.x * v.x + n.y * v.y + n.z * v.z;
    if (nv >= DI_SHADING_MIN_NV) {
        return n;
    }
    vec3 m = n + v * (DI_SHADING_MIN_NV - nv);
    return m * inversesqrt(m.x * m.x + m.y * m.y + m.z * m.z);
}

vec3 di_shading_local(vec3 w, vec3 t, vec3 b, vec3 n) {
    return vec3(w.x * t.x + w.y * t.y + w.z * t.z, w.x * b.x + w.y * b.y + w.z * b.z,
                w.x * n.x + w.y * n.y + w.z * n.z);
}

vec3 di_shading_ambient(PbrSample s, float ambient) {
    return s.albedo * (ambient * s.ao);
}

vec3 di_shading_learned(PbrSample s, DiShadingGeometry g, float ambient) {
    vec3 n = di_shading_visible_normal(s.normal_ts, g.v);
    vec3 t, b;
    di_shading_frame(n, t, b);
    vec4 x[BRDF_IN_BLOCKS];
    x[0] = vec4(s.roughness, 0.0, 0.0, 0.0);
    vec4 y[BRDF_OUT_BLOCKS];
    brdf_eval(x, y);
    DiDisney d;
    d.ggx = y[0].xyz;
    d.smith = y[0].w;
    d.diff = y[1];
    d.coef = y[2];
    d.gloss = y[3].xy;
    d.sheen_tint = 0.5;
    d.k = vec3(0.0, 0.02, 0.0);
    d.albedo = s.albedo;
    vec3 f = di_disney_brdf(d, di_shading_local(g.l, t, b, n), di_shading_local(g.v, t, b, n));
    return f * g.e + di_shading_ambient(s, ambient);
}

vec3 di_shading_analytic(PbrSample s, DiShadingGeometry g, float ambient) {
    vec3 n = di_shading_visible_normal(s.normal_ts, g.v);
    vec3 t, b;
    di_shading_frame(n, t, b);
    DisneyMaterial m;
    m.base_color = s.albedo;
    m.roughness = s.roughness;
    m.metallic = 0.0;
    m.anisotropic = 0.0;
    m.subsurface = 0.0;
    m.specular = 0.5;
    m.specular_tint = 0.0;
    m.sheen = 0.0;
    m.sheen_tint = 0.5;
    m.clearcoat = 0.0;
    m.clearcoat_gloss = 1.0;
    vec3 f = disney_brdf(m, di_shading_local(g.l, t, b, n), di_shading_local(g.v, t, b, n));
    return f * g.e + di_shading_ambient(s, ambient);
}
