// Neural appearance on a rasterised mesh (Real-Time Neural Appearance Models, NVIDIA 2024):
// deferred like passes/mesh_prt — the G-buffer (runtime/geometry.py) gives position, normal, uv,
// tangent and the uv footprint per pixel; the latent pyramid, decoder and sampler run once per
// visible pixel and sample. A stochastic program (ProgramSpec.accumulate): the level choice and the
// environment estimator draw from lib/random with u_sample_index, and the runtime keeps the
// running mean. Views (u_na_view, VIEWS in techniques/neural_appearance/__init__.py; NA_VIEW_*: <choices>):
// neural | reference | split (left reference, right neural) | error (|neural - reference| x
// u_na_error_scale) | level (the chosen pyramid level, a ramp) | latents (3 of the 8 channels,
// page u_na_latent_page: 0 -> z0..2, 1 -> z3..5, 2 -> z6..7).
// Linear radiance; alpha 1 on the mesh, 0 in the background (which shows the environment).
#include <lib/camera>
#include <lib/gbuffer>
#include <choices>
#include <lib/na_shading>
#include <lib/na_settings>

uniform vec2 u_size;
uniform int u_na_latent_page;
uniform sampler2D u_gbuffer_uv_grad;
layout(location = 0) out vec4 frag_color;

vec3 na_shade(NaPoint s, bool neural, uvec2 px) {
    if (u_na_lighting == NA_LIGHTING_ENVIRONMENT)
        return na_environment(s, neural, u_na_sampling, u_na_mis != 0, px, u_sample_index);
    return na_lights(s, neural, u_light_count);
}

vec3 na_ramp(float x) {   // level 0 blue .. coarsest red
    return clamp(vec3(1.5 - abs(4.0 * x - 3.0), 1.5 - abs(4.0 * x - 2.0), 1.5 - abs(4.0 * x - 1.0)), 0.0, 1.0);
}

void main() {
    ivec2 ipx = ivec2(gl_FragCoord.xy);
    uvec2 px = uvec2(ipx);
    NaPoint s;
    vec3 rd;
    if (!gbuffer_pixel(u_size, rd, s.position, s.n)) {
        frag_color = vec4(env_radiance(rd), 0.0);
        return;
    }
    vec4 tangent = texelFetch(u_gbuffer_tangent, ipx, 0);
    vec3 t = tangent.xyz - s.n * dot(s.n, tangent.xyz);
    s.t = t * inversesqrt(max(dot(t, t), 1e-30));
    s.b = cross(s.n, s.t) * (tangent.w < 0.0 ? -1.0 : 1.0);
    s.view = na_local(s, -rd);
    s.uv = texelFetch(u_gbuffer_uv, ipx, 0).xy;
    s.lod = na_lod(texelFetch(u_gbuffer_uv_grad, ipx, 0), u_na_level_bias);
    float level = na_choose_level(s.lod, random_uniform2(px, u_sample_index, 0).x);
    s.z = na_latent(s.uv, level);
    na_fetch_parameters(s.uv, s.lod, s.p0, s.p1, s.p2);

    vec3 colour;
    if (u_na_view == NA_VIEW_LEVEL) {
        colour = na_ramp(level / max(float(NA_LATENT_LEVELS - 1), 1.0));
    } else if (u_na_view == NA_VIEW_LATENTS) {
        vec4 z = u_na_latent_page == 0 ? s.z.a : (u_na_latent_page == 1 ? vec4(s.z.a.w, s.z.b.xyz) : vec4(s.z.b.zw, 0.0, 0.0));
        colour = 0.5 + 0.25 * z.xyz;
    } else if (u_na_view == NA_VIEW_ERROR) {
        colour = abs(na_shade(s, true, px) - na_shade(s, false, px)) * u_na_error_scale;
    } else {
        bool neural = u_na_view == NA_VIEW_NEURAL || (u_na_view == NA_VIEW_SPLIT && gl_FragCoord.x >= 0.5 * u_size.x);
        colour = na_shade(s, neural, px);
    }
    frag_color = vec4(colour, 1.0);
}
