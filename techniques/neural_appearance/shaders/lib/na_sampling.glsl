// BRDF sampling of the neural material's Monte Carlo environment estimate: the sampling decoder's
// proxy lobe (learned or isotropic, lib/proxy_lobe) or BRDF-agnostic cosine-weighted directions.
// Directions in the local frame of the geometric surface (z = normal). NA_SAMPLING_*: the program's
// choices (SAMPLING in techniques/neural_appearance/__init__.py), generated into <choices>.
#include <lib/proxy_lobe>
#include <choices>

#ifndef NA_PI
#define NA_PI 3.14159265
#endif

float na_bsdf_pdf(int sampling, ProxyLobe lobe, vec3 view, vec3 light) {
    if (sampling == NA_SAMPLING_COSINE) return max(light.z, 0.0) * (1.0 / NA_PI);
    return proxy_pdf(lobe, view, light);
}

vec3 na_bsdf_sample(int sampling, ProxyLobe lobe, vec3 view, vec3 u) {
    if (sampling == NA_SAMPLING_COSINE) {
        float r = sqrt(u.y), phi = 2.0 * NA_PI * u.z;
        return vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u.y)));
    }
    return proxy_sample(lobe, view, u);
}
