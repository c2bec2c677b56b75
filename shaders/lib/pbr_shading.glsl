// A PBR channel set shaded on a mesh, shared by the techniques that decode one: albedo (linear),
// a tangent-space normal, roughness, metallic and AO.
// Material: Disney (lib/brdf) with specular 0.5, roughness and metallic from the set; point lights
// (inverse-square) plus the SH environment: its Lambert term for the diffuse part, scaled by AO
// and (1 - metallic), and for metals the SH radiance about the mirror direction (a coarse
// stand-in for a prefiltered specular environment; exact for metallic 0, where it is absent).
// A torch twin for metallic 0 (same operations in the same order) sits with the PBR-set technique's trainer.
#include <lib/brdf>
#include <lib/spherical_harmonics>
#include <lib/lights>
#include <lib/pbr_sample>

vec3 pbr_local(vec3 w, vec3 t, vec3 b, vec3 n) {
    return vec3(w.x * t.x + w.y * t.y + w.z * t.z, w.x * b.x + w.y * b.y + w.z * b.z,
                w.x * n.x + w.y * n.y + w.z * n.z);
}

// p: world position; ng: unit geometric (interpolated) normal; tangent: interpolated tangent and
// handedness (G-buffer); rd: unit view ray.
vec3 pbr_shade(PbrSample s, vec3 p, vec3 ng, vec4 tangent, vec3 rd, in vec3 sh[SH_COEFFS], int light_count) {
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
    DisneyMaterial m = DisneyMaterial(s.albedo, s.roughness, s.metallic, 0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 1.0);
    vec3 v = pbr_local(-rd, ts, bs, n);
    vec3 colour = s.albedo * ((1.0 - s.metallic) * s.ao * BRDF_INV_PI) * sh_irradiance(n, sh);
    if (s.metallic > 0.0) {   // a metal's environment: the SH radiance about the mirror direction
        vec3 r = reflect(rd, n);
        colour += s.albedo * (s.metallic * s.ao) * max(sh_radiance(r, sh), vec3(0.0));
    }
    for (int i = 0; i < INSHADE_MAX_LIGHTS; ++i) {
        if (i >= scene_lights(light_count)) break;
        vec3 d = u_lights[i].xyz - p;
        float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
        vec3 l = pbr_local(d * inversesqrt(d2), ts, bs, n);
        colour += disney_brdf(m, l, v) * (u_lights[i].w / d2);
    }
    return colour;
}
