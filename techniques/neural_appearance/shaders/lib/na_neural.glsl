// The neural material (Real-Time Neural Appearance Models, NVIDIA 2024 §2): latents fetched from
// the pyramid at one stochastically chosen level (§2.1), decoded by an MLP with learned shading
// frames (§2.2); the importance-sampling decoder's proxy lobe (§2.3). The networks are generated
// chunks (codegen of the asset's bundles): <network_latents> (u, v, level) -> 8 latents,
// <network_dec16|32|64> (z, light, view) -> log(1 + f cos) mapped back by expm1, <network_smp>
// and <network_iso> (z, view) -> 9 proxy parameters. <na_latents_info> (generated from the
// latents bundle) defines NA_LATENT_RES and NA_LATENT_LEVELS. NA_DECODER (16, 32 or 64) picks
// the decoder; the two others are never called, so the compiler drops them.
// Torch twin: techniques/neural_appearance/twin.py.
#include <na_latents_info>
#include <network_latents>
#include <network_dec16>
#include <network_dec32>
#include <network_dec64>
#include <network_smp>
#include <network_iso>
#include <lib/proxy_lobe>

#ifndef NA_DECODER
#define NA_DECODER 64
#endif

// The pyramid level for a uv footprint (dFdx(uv), dFdy(uv) from the G-buffer): log2 of the
// footprint's side in finest-level texels, from its area (§2.1), plus a bias; clamped to the pyramid.
float na_lod(vec4 uv_grad, float bias) {
    vec2 dx = uv_grad.xy * float(NA_LATENT_RES);
    vec2 dy = uv_grad.zw * float(NA_LATENT_RES);
    float area = abs(dx.x * dy.y - dx.y * dy.x);
    return clamp(0.5 * log2(max(area, 1e-20)) + bias, 0.0, float(NA_LATENT_LEVELS - 1));
}

// One of the two nearest levels, the coarser with probability fract(lod) (Russian roulette: §2.1).
float na_choose_level(float lod, float xi) {
    float base = floor(lod);
    return min(base + (xi < lod - base ? 1.0 : 0.0), float(NA_LATENT_LEVELS - 1));
}

struct NaLatent {
    vec4 a;
    vec4 b;
};

NaLatent na_latent(vec2 uv, float level) {
    vec4 x[LATENTS_IN_BLOCKS];
    x[0] = vec4(uv, level, 0.0);
    vec4 y[LATENTS_OUT_BLOCKS];
    latents_eval(x, y);
    return NaLatent(y[0], y[1]);
}

// Cosine-weighted BRDF f cos(theta_light) of the neural material; light/view in the local frame
// of the geometric surface (z = normal). Zero below either horizon (the reference is, too).
vec3 na_neural(NaLatent z, vec3 light, vec3 view) {
    if (light.z <= 0.0 || view.z <= 0.0) return vec3(0.0);
    vec4 x[4];
    x[0] = z.a;
    x[1] = z.b;
    x[2] = vec4(light, view.x);
    x[3] = vec4(view.yz, 0.0, 0.0);
    vec4 y[1];
#if NA_DECODER == 16
    dec16_eval(x, y);
#elif NA_DECODER == 32
    dec32_eval(x, y);
#else
    dec64_eval(x, y);
#endif
    return max(y[0].xyz, vec3(0.0));
}

// The sampling decoder's proxy lobe for this latent and view (queried once per pixel and sample).
ProxyLobe na_lobe(NaLatent z, vec3 view, bool isotropic) {
    vec4 x[3];
    x[0] = z.a;
    x[1] = z.b;
    x[2] = vec4(view, 0.0);
    vec4 y[3];
    if (isotropic) {
        iso_eval(x, y);
    } else {
        smp_eval(x, y);
    }
    return proxy_lobe(y[0], y[1], y[2].x);
}
