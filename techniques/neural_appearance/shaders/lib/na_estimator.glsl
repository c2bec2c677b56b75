// The directions of one Monte Carlo sample of the environment's reflected radiance (pixel px,
// sample index k), the same for the layered materials (lib/na_shading) and a glTF file's
// (lib/na_gltf): one BRDF sample (the proxy lobe or cosine, per `sampling`) and, with MIS, one
// environment sample, each weighted by the power heuristic over its pdf. The caller sums
// f cos x radiance x weight over the used directions, with its own material and environment.
#include <lib/na_neural>
#include <lib/na_sampling>
#include <lib/environment>
#include <lib/random>
#include <choices>

struct NaEnvSample {
    bool used[2];     // the BRDF sample, the environment sample: whether it adds anything
    vec3 light[2];    // local direction (x = t, y = b, z = n)
    vec3 dir[2];      // the same, in world space
    float weight[2];  // MIS weight / pdf
};

// At a surface with world frame (t, b, n), latents z, local view direction `view`.
NaEnvSample na_env_sample(NaLatent z, vec3 view, vec3 t, vec3 b, vec3 n, int sampling, bool mis, uvec2 px, int k) {
    ProxyLobe lobe = na_lobe(z, view, sampling == NA_SAMPLING_ISOTROPIC);
    NaEnvSample e;
    vec3 light = na_bsdf_sample(sampling, lobe, view, random_uniform3(px, k, 1));
    float pdf = na_bsdf_pdf(sampling, lobe, view, light);
    e.used[0] = light.z > 0.0 && pdf > 0.0;
    e.light[0] = light;
    if (e.used[0]) {
        vec3 dir = t * light.x + b * light.y + n * light.z;
        float w = mis ? mis_power(pdf, env_pdf(dir)) : 1.0;
        e.dir[0] = dir;
        e.weight[0] = w / pdf;
    }
    e.used[1] = false;
    if (mis) {
        float env_p;
        vec3 dir = env_sample(random_uniform2(px, k, 2), env_p);
        vec3 l = vec3(dot(dir, t), dot(dir, b), dot(dir, n));
        e.used[1] = l.z > 0.0 && env_p > 0.0;
        e.light[1] = l;
        e.dir[1] = dir;
        if (e.used[1]) {
            float w = mis_power(env_p, na_bsdf_pdf(sampling, lobe, view, l));
            e.weight[1] = w / env_p;
        }
    }
    return e;
}
