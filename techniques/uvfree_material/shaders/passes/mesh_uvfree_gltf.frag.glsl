// UV-free neural material of a glTF file (Walloner 2024) against the file's own material: the
// G-buffer's pixel gives the reference surface (lib/gltf_material gltf_surface: the file's textures
// at the mesh's uv, what passes/gltf_pbr.frag draws); where the network is shown, the visibility
// buffer's (face, barycentrics) point is decoded (lib/uvf_gltf) and its channels replace the file's.
// Both sides are shaded by gltf_shade (the spec's BRDF, the scene's lights and SH environment).
// u_uvg_view (GLTF_VIEWS in techniques/uvfree_material/__init__.py): reference | decoded | split
// (left half reference, right half network) | error (|network - reference| x u_uvg_error_scale, of the
// channel shown). u_uvg_channel (GLTF_CHANNEL_VIEWS): shaded, or one
// channel as passes/gltf_pbr.frag shows it (linear base colour, mapped normal 0.5 + 0.5 n, metallic,
// roughness, occlusion, emission). UVG_VIEW_*, UVG_CHANNEL_*: generated into <choices>.
#include <lib/gltf_gbuffer>
#include <lib/uvf_gltf>
#include <choices>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform usampler2D u_gbuffer_primitive;
uniform sampler2D u_gbuffer_barycentric;
uniform int u_uvg_view;
uniform int u_uvg_channel;
uniform float u_uvg_error_scale;
uniform int u_light_count;
layout(location = 0) out vec4 frag_color;

// What the pixel shows of surface s: shaded, or the chosen channel.
vec3 channel(GltfSurface s, GltfPixel g) {
    if (u_uvg_channel == UVG_CHANNEL_BASE_COLOR) return s.s.base_color;
    if (u_uvg_channel == UVG_CHANNEL_NORMAL) return 0.5 + 0.5 * s.n;
    if (u_uvg_channel == UVG_CHANNEL_METALLIC) return vec3(s.s.metallic);
    if (u_uvg_channel == UVG_CHANNEL_ROUGHNESS) return vec3(s.s.roughness);
    if (u_uvg_channel == UVG_CHANNEL_OCCLUSION) return vec3(s.occlusion);
    if (u_uvg_channel == UVG_CHANNEL_EMISSIVE) return s.emissive;
    return gltf_shade(s, g.p, g.v, u_sh, u_light_count);
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    GltfPixel g;
    GltfSurface s;
    bool error = u_uvg_view == UVG_VIEW_ERROR;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, s)) {   // the sky: the same on both sides
        frag_color = vec4(error ? vec3(0.0) : sh_background(-g.v, u_sh), 1.0);
        return;
    }
    GltfSurface reference = s;
    bool network = u_uvg_view == UVG_VIEW_DECODED || error
                   || (u_uvg_view == UVG_VIEW_SPLIT && gl_FragCoord.x >= 0.5 * u_size.x);
    if (network) {
        uvg_decode(texelFetch(u_gbuffer_primitive, px, 0).x, texelFetch(u_gbuffer_barycentric, px, 0).xy, g.material,
                   g.n, g.tangent, g.v, s);
    }
    vec3 c = channel(s, g);
    if (error) c = abs(c - channel(reference, g)) * u_uvg_error_scale;
    frag_color = vec4(c, 1.0);
}
