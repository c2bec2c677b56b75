// The neural material in place of a glTF file's material (neural_appearance --gltf): the decoder's
// f cos under the scene's lights and, estimated by Monte Carlo as for the layered materials
// (lib/na_shading: one BRDF sample from the proxy lobe or cosine, MIS with one environment sample,
// accumulated over frames), under the SH environment the reference (lib/gltf_material gltf_shade)
// is lit by; the environment map's importance sampling (lib/environment) only proposes directions.
// Occlusion (on the environment) and emission are the file's, from gltf_surface: no part of the
// learnt BRDF. Local frame: the geometric one gltf_surface builds (gltf_tangent_frame, turned over on
// the back of a double-sided surface): x = t, y = b, z = ng, as in training (gltf_source.py).
#include <lib/na_neural>
#include <lib/na_estimator>
#include <lib/gltf_material>
#include <choices>

// Training draws views above the geometric horizon only; interpolated normals put some silhouette
// pixels below it. Their view is lifted to this elevation (its sine), the nearest trained direction.
#define NA_GLTF_MIN_VIEW_Z 0.02

struct NaGltfPoint {
    vec3 t;            // geometric frame (world space)
    vec3 b;
    vec3 n;
    vec3 position;
    vec3 view;         // local direction to the viewer, above the horizon
    NaLatent z;        // latents at the stochastically chosen level
    float occlusion;   // the file's, on the environment's light
    vec3 emissive;     // the file's
};

vec3 na_gltf_local(NaGltfPoint s, vec3 w) {
    return vec3(dot(w, s.t), dot(w, s.b), dot(w, s.n));
}

// The frame of material m's surface at a G-buffer pixel, as gltf_surface orients it.
void na_gltf_frame(int m, vec3 ng, vec4 tangent, vec3 v, out vec3 t, out vec3 b, out vec3 n) {
    gltf_tangent_frame(ng, tangent, t, b);
    n = ng;
    if (material_param(m, 5).x > 0.5 && gltf_dot(ng, v) < 0.0) {   // the back of a double-sided surface
        n = -ng; t = -t; b = -b;
    }
}

vec3 na_gltf_view(vec3 local_view) {
    if (local_view.z >= NA_GLTF_MIN_VIEW_Z) return local_view;
    vec2 xy = local_view.xy * inversesqrt(max(dot(local_view.xy, local_view.xy), 1e-30));
    return vec3(xy * sqrt(1.0 - NA_GLTF_MIN_VIEW_Z * NA_GLTF_MIN_VIEW_Z), NA_GLTF_MIN_VIEW_Z);
}

vec3 na_gltf_lights(NaGltfPoint s, int light_count) {
    vec3 sum = vec3(0.0);
    for (int i = 0; i < INSHADE_MAX_LIGHTS; ++i) {
        if (i >= scene_lights(light_count)) break;
        vec3 to_light;
        float scale;
        scene_light(i, s.position, to_light, scale);
        sum += na_neural(s.z, na_gltf_local(s, to_light), s.view) * (u_lights[i].w * scale);
    }
    return sum;
}

// The radiance the reference's environment term integrates (gltf_shade clamps it the same way).
vec3 na_gltf_sky(vec3 dir, in vec3 sh[SH_COEFFS]) {
    return max(sh_radiance(dir, sh), vec3(0.0));
}

// One Monte Carlo sample of the SH environment's reflected radiance (pixel px, sample index k).
vec3 na_gltf_environment(NaGltfPoint s, in vec3 sh[SH_COEFFS], int sampling, bool mis, uvec2 px, int k) {
    NaEnvSample e = na_env_sample(s.z, s.view, s.t, s.b, s.n, sampling, mis, px, k);
    vec3 sum = vec3(0.0);
    if (e.used[0]) sum += na_neural(s.z, e.light[0], s.view) * na_gltf_sky(e.dir[0], sh) * e.weight[0];
    if (e.used[1]) sum += na_neural(s.z, e.light[1], s.view) * na_gltf_sky(e.dir[1], sh) * e.weight[1];
    return sum;
}

// What the neural surface sends towards the camera: lights, (environment: the SH sky, occluded),
// emission; the terms gltf_shade sums for the reference.
vec3 na_gltf_shade(NaGltfPoint s, bool environment, in vec3 sh[SH_COEFFS], int sampling, bool mis, int light_count,
                   uvec2 px, int k) {
    vec3 colour = na_gltf_lights(s, light_count) + s.emissive;
    if (environment) colour += na_gltf_environment(s, sh, sampling, mis, px, k) * s.occlusion;
    return colour;
}
