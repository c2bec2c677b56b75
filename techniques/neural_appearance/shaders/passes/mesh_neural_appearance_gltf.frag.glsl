// Neural appearance of a glTF file's material (neural_appearance --gltf) on the file's own mesh,
// deferred like passes/mesh_neural_appearance: per G-buffer pixel, the file's material through
// lib/gltf_material (gltf_surface + gltf_shade: the reference, the same pixels passes/gltf_pbr.frag
// draws), and where the surface is the learnt material (NA_GLTF_MATERIAL, <na_gltf_info>) the neural
// material (lib/na_gltf) at latent coordinates (uv - NA_UV_ORIGIN) * NA_UV_SCALE. Other materials are
// the reference on both sides. A stochastic program (ProgramSpec.accumulate): the level choice and
// the environment estimate draw from lib/random with u_sample_index.
// Views (u_na_view, GLTF_VIEWS in techniques/neural_appearance/__init__.py; NA_VIEW_*: <choices>):
// split (left reference, right neural) | reference | neural | error (|neural - reference| x
// u_na_error_scale). Lighting (u_na_lighting, GLTF_LIGHTING): shaded (lights, SH environment and
// emission, as gltf_pbr) | lights (lights and emission, no environment: deterministic but for the
// level choice). Linear radiance; the background is the SH sky, as gltf_pbr draws it.
#include <lib/gltf_gbuffer>
#include <choices>
#include <na_latents_info>
#include <na_gltf_info>
#include <lib/na_gltf>
#include <lib/na_settings>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
layout(location = 0) out vec4 frag_color;

void main() {
    ivec2 ipx = ivec2(gl_FragCoord.xy);
    uvec2 px = uvec2(ipx);
    GltfPixel g;
    GltfSurface surface;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, surface)) {
        frag_color = vec4(sh_background(-g.v, u_sh), 1.0);
        return;
    }
    vec3 p = g.p, ng = g.n, v = g.v;
    vec4 tangent = g.tangent;
    int m = g.material;
    bool environment = u_na_lighting == NA_LIGHTING_SHADED;
    // lights only: gltf_shade under a black sky (its environment term 0) is lights + emission
    vec3 none[SH_COEFFS];
    for (int i = 0; i < SH_COEFFS; ++i) none[i] = vec3(0.0);
    vec3 reference = environment ? gltf_shade(surface, p, v, u_sh, u_light_count)
                                 : gltf_shade(surface, p, v, none, u_light_count);
    bool right = gl_FragCoord.x >= 0.5 * u_size.x;
    bool neural_side = u_na_view == NA_VIEW_NEURAL || u_na_view == NA_VIEW_ERROR
                    || (u_na_view == NA_VIEW_SPLIT && right);
    if (m != NA_GLTF_MATERIAL || !neural_side) {   // the file's material: the reference on both sides
        frag_color = vec4(u_na_view == NA_VIEW_ERROR ? vec3(0.0) : reference, 1.0);
        return;
    }
    NaGltfPoint s;
    s.position = p;
    na_gltf_frame(m, ng, tangent, v, s.t, s.b, s.n);
    s.view = na_gltf_view(na_gltf_local(s, v));
    vec2 x = (g.uv.xy - NA_UV_ORIGIN) * NA_UV_SCALE;
    float lod = na_lod(texelFetch(u_gbuffer_uv_grad, ipx, 0) * vec4(NA_UV_SCALE, NA_UV_SCALE), u_na_level_bias);
    s.z = na_latent(x, na_choose_level(lod, random_uniform2(px, u_sample_index, 0).x));
    s.occlusion = surface.occlusion;
    s.emissive = surface.emissive;
    vec3 neural = na_gltf_shade(s, environment, u_sh, u_na_sampling, u_na_mis != 0, u_light_count, px, u_sample_index);
    frag_color = vec4(u_na_view == NA_VIEW_ERROR ? abs(neural - reference) * u_na_error_scale : neural, 1.0);
}
