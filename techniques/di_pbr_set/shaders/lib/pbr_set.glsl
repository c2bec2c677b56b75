// A PBR texture set (Differentiable Indirection, Datta et al. 2023 4.2.1: "for PBR textures k includes albedo, normal, AO, roughness")
// shaded on a mesh. Eight lanes, in techniques/di_pbr_set/train.py LANES order, as two vec4:
//   a = (albedo.rgb [sRGB-encoded], normal.x), b = (normal.y, normal.z, roughness, ao)
// with the tangent-space normal stored as 0.5 + 0.5 n (x along +u, y along +v, z out). The
// compressed set (the DI bundle) and the uncompressed one (two RGBA8 textures of the same lanes)
// feed the same pbr_set_shade, so a side-by-side view differs by the compression alone.
// Material: Disney (lib/brdf) with metallic 0 and specular 0.5, roughness from the set; point
// lights (inverse-square) plus the SH environment's Lambert term scaled by the AO lane.
// techniques/di_pbr_set/train.py (unpack, shade) is the torch twin: same operations in the same order.
#include <lib/colour>
#include <lib/brdf>
#include <lib/spherical_harmonics>
#include <lib/lights>

struct PbrSetSample {
    vec3 albedo;      // linear
    vec3 normal_ts;   // unit, tangent space
    float roughness;
    float ao;
};

PbrSetSample pbr_set_unpack(vec4 a, vec4 b) {
    PbrSetSample s;
    s.albedo = srgb_eotf(clamp(a.xyz, 0.0, 1.0));
    vec3 n = vec3(a.w, b.x, b.y) * 2.0 - 1.0;
    float len2 = n.x * n.x + n.y * n.y + n.z * n.z;
    s.normal_ts = len2 > 1e-12 ? n * inversesqrt(len2) : vec3(0.0, 0.0, 1.0);
    s.roughness = clamp(b.z, 0.0, 1.0);
    s.ao = clamp(b.w, 0.0, 1.0);
    return s;
}

vec3 pbr_set_local(vec3 w, vec3 t, vec3 b, vec3 n) {
    return vec3(w.x * t.x + w.y * t.y + w.z * t.z, w.x * b.x + w.y * b.y + w.z * b.z,
                w.x * n.x + w.y * n.y + w.z * n.z);
}

// p: world position; ng: unit geometric (interpolated) normal; tangent: interpolated tangent and
// handedness (G-buffer); rd: unit view ray.
vec3 pbr_set_shade(PbrSetSample s, vec3 p, vec3 ng, vec4 tangent, vec3 rd, in vec3 sh[SH_COEFFS],
                   int light_count) {
    // tangent frame: Gram-Schmidt against the normal, bitangent by handedness
    vec3 t = tangent.xyz - ng * (ng.x * tangent.x + ng.y * tangent.y + ng.z * tangent.z);
    t = t * inversesqrt(max(t.x * t.x + t.y * t.y + t.z * t.z, 1e-30));
    vec3 b = cross(ng, t) * (tangent.w < 0.0 ? -1.0 : 1.0);
    vec3 n = t * s.normal_ts.x + b * s.normal_ts.y + ng * s.normal_ts.z;
    n = n * inversesqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    // shading frame around the mapped normal (the BRDF is isotropic: any tangent will do)
    vec3 ts = t - n * (n.x * t.x + n.y * t.y + n.z * t.z);
    ts = ts * inversesqrt(max(ts.x * ts.x + ts.y * ts.y + ts.z * ts.z, 1e-30));
    vec3 bs = cross(n, ts);
    DisneyMaterial m = DisneyMaterial(s.albedo, s.roughness, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 1.0);
    vec3 v = pbr_set_local(-rd, ts, bs, n);
    vec3 colour = s.albedo * (s.ao * BRDF_INV_PI) * sh_irradiance(n, sh);
    for (int i = 0; i < INSHADE_MAX_LIGHTS; ++i) {
        if (i >= scene_lights(light_count)) break;
        vec3 d = u_lights[i].xyz - p;
        float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
        vec3 l = pbr_set_local(d * inversesqrt(d2), ts, bs, n);
        colour += disney_brdf(m, l, v) * (u_lights[i].w / d2);
    }
    return colour;
}
