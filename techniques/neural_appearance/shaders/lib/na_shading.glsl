// Shading of the neural and the reference material with the same lights, estimator and random
// numbers, so that a split or error view differs by the material alone.
// Lighting: NA_LIGHTING_LIGHTS (the scene's point and directional lights, decoder only) or
// NA_LIGHTING_ENVIRONMENT (the environment map by Monte Carlo: one BRDF-proxy sample, combined by
// the power heuristic with one environment sample when MIS is on; accumulated over frames).
// BRDF sampling: NA_SAMPLING_LEARNED (the sampler decoder's proxy), _ISOTROPIC (the isotropic
// baseline proxy) or _COSINE (BRDF-agnostic cosine-weighted). No shadowing: lights and
// environment reach every point with n.l > 0 (as in the paper's material-only comparisons).
// NA_LIGHTING_* and NA_SAMPLING_*: the program's choices (LIGHTING, SAMPLING in
// techniques/neural_appearance/__init__.py), generated into <choices>.
#include <lib/na_neural>
#include <lib/na_reference>
#include <lib/na_estimator>
#include <lib/lights>
#include <lib/environment>
#include <choices>


struct NaPoint {
    vec3 t;            // tangent frame of the geometric surface (world space)
    vec3 b;
    vec3 n;
    vec3 position;
    vec3 view;         // local direction to the viewer
    vec2 uv;
    float lod;         // continuous pyramid level of the footprint
    NaLatent z;        // latents at the stochastically chosen level
    vec4 p0;           // reference parameters (textures through their own mips at lod)
    vec4 p1;
    vec4 p2;
};

vec3 na_local(NaPoint s, vec3 w) {
    return vec3(dot(w, s.t), dot(w, s.b), dot(w, s.n));
}

// f cos of the shown material: the neural decoder or the reference.
vec3 na_reflectance_of(NaPoint s, bool neural, vec3 light) {
    if (neural) return na_neural(s.z, light, s.view);
    return na_reflectance(s.p0, s.p1, s.p2, light, s.view);
}

vec3 na_lights(NaPoint s, bool neural, int light_count) {
    vec3 sum = vec3(0.0);
    for (int i = 0; i < INSHADE_MAX_LIGHTS; ++i) {
        if (i >= scene_lights(light_count)) break;
        vec3 to_light;
        float scale;
        scene_light(i, s.position, to_light, scale);
        sum += na_reflectance_of(s, neural, na_local(s, to_light)) * (u_lights[i].w * scale);
    }
    return sum;
}

// One Monte Carlo sample of the environment's reflected radiance (pixel px, sample index k).
vec3 na_environment(NaPoint s, bool neural, int sampling, bool mis, uvec2 px, int k) {
    NaEnvSample e = na_env_sample(s.z, s.view, s.t, s.b, s.n, sampling, mis, px, k);
    vec3 sum = vec3(0.0);
    if (e.used[0]) sum += na_reflectance_of(s, neural, e.light[0]) * env_radiance(e.dir[0]) * e.weight[0];
    if (e.used[1]) sum += na_reflectance_of(s, neural, e.light[1]) * env_radiance(e.dir[1]) * e.weight[1];
    return sum;
}
