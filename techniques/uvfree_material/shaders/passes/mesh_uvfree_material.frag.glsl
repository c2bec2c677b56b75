// UV-free neural material on a rasterised mesh (Walloner 2024): the G-buffer's visibility buffer
// (ProgramSpec.visibility: face id + barycentrics per pixel) names the surface point, the material
// network <network_mat> (mesh_features -> MLP) decodes it once per visible pixel, and
// lib/pbr_shading shades the channels with the scene's point lights and SH environment. The
// mesh's uvs serve only the reference view and the tangent frame of the normal map.
// u_uvf_view (VIEWS in techniques/uvfree_material/__init__.py): decoded | reference | split (left
// reference, right decoded) | error (|decoded - reference| x u_uvf_error_scale).
// u_uvf_channel (CHANNEL_VIEWS): shaded, or one channel group as stored (albedo sRGB-encoded,
// normal n * 0.5 + 0.5, roughness, metallic, AO as grey), shown so the display's sRGB encoding
// puts the stored value on screen. u_uvf_wireframe: off | triangles (face boundaries) | level
// (boundaries of the sub-triangles of level u_uvf_wire_level), found from the neighbours' ids
// (only between cells three or more pixels across: finer than that, the overlay fades out).
// UVF_VIEW_*, UVF_CHANNEL_*, UVF_WIREFRAME_*: the program's choices, generated into <choices>.
// UVF_DECODER 0 (the scene setting "decoder": off) compiles the decoder out: the reference-only
// shader, for timing the decode (a software rasteriser may run both sides of a uniform branch).
// Linear radiance; alpha 1 on the mesh, 0 in the background (the environment).
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/uvf_material>
#include <lib/mesh_features>
#include <choices>

#ifndef UVF_DECODER
#define UVF_DECODER 1
#endif

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_light_count;
uniform int u_uvf_view;
uniform int u_uvf_channel;
uniform int u_uvf_wireframe;
uniform int u_uvf_wire_level;
uniform float u_uvf_error_scale;
uniform usampler2D u_gbuffer_primitive;
uniform sampler2D u_gbuffer_barycentric;
layout(location = 0) out vec4 frag_color;

vec3 uvf_show(UvfChannels c, vec3 p, vec3 n, vec4 tangent, vec3 rd) {
    if (u_uvf_channel == UVF_CHANNEL_SHADED) return pbr_shade(uvf_unpack(c), p, n, tangent, rd, u_sh, u_light_count);
    vec3 stored = u_uvf_channel == UVF_CHANNEL_ALBEDO ? c.albedo
                : (u_uvf_channel == UVF_CHANNEL_NORMAL ? c.normal : vec3(c.rma[u_uvf_channel - UVF_CHANNEL_ROUGHNESS]));
    return srgb_eotf(clamp(stored, 0.0, 1.0));
}

// The cell a point falls in at `level`: (face, sub-triangle corner i, j, upright) packed for comparison.
uvec4 uvf_cell(ivec2 px, int level) {
    uint k = texelFetch(u_gbuffer_primitive, px, 0).x;
    ivec2 w[3];
    vec3 weight;
    mf_subtriangle(texelFetch(u_gbuffer_barycentric, px, 0).xy, level, w, weight);
    return uvec4(k, uvec2(w[0]), uint(w[1].x > w[0].x));   // upright: w[1] = w[0] + (1, 0)
}

bool uvf_same(uvec4 a, uvec4 b) {
    return u_uvf_wireframe == UVF_WIREFRAME_TRIANGLES ? a.x == b.x : a == b;
}

// A boundary between this pixel's cell and the next pixel's (+x or +y), drawn only where this
// pixel's cell also holds the two previous pixels: cells narrower than three pixels draw no lines,
// so a level finer than the screen resolves fades out instead of covering the surface.
bool uvf_edge(ivec2 px) {
    if (u_uvf_wireframe == UVF_WIREFRAME_OFF) return false;
    int level = u_uvf_wireframe == UVF_WIREFRAME_TRIANGLES ? 0 : u_uvf_wire_level;
    uvec4 here = uvf_cell(px, level);
    ivec2 size = ivec2(u_size);
    for (int d = 0; d < 2; ++d) {
        ivec2 step = d == 0 ? ivec2(1, 0) : ivec2(0, 1);
        ivec2 q = px + step;
        ivec2 b = px - 2 * step;
        if (q.x >= size.x || q.y >= size.y || b.x < 0 || b.y < 0) continue;
        if (texelFetch(u_gbuffer_position, q, 0).w == 0.0 || texelFetch(u_gbuffer_position, b, 0).w == 0.0) continue;
        if (!uvf_same(here, uvf_cell(q, level)) && uvf_same(here, uvf_cell(px - step, level))
            && uvf_same(here, uvf_cell(b, level))) return true;
    }
    return false;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 rd, p, n;
    if (!gbuffer_pixel(u_size, rd, p, n)) {
        frag_color = vec4(sh_background(rd, u_sh), 0.0);
        return;
    }
    vec4 tangent = texelFetch(u_gbuffer_tangent, px, 0);
    bool decoded = u_uvf_view == UVF_VIEW_DECODED || u_uvf_view == UVF_VIEW_ERROR
                   || (u_uvf_view == UVF_VIEW_SPLIT && gl_FragCoord.x >= 0.5 * u_size.x);
    bool reference = u_uvf_view != UVF_VIEW_DECODED && !(u_uvf_view == UVF_VIEW_SPLIT && decoded);
    vec3 colour = vec3(0.0);
#if UVF_DECODER
    if (decoded) {
        uint k = texelFetch(u_gbuffer_primitive, px, 0).x;
        colour = uvf_show(uvf_decode(k, texelFetch(u_gbuffer_barycentric, px, 0).xy), p, n, tangent, rd);
    }
#endif
    if (reference) {
        vec3 r = uvf_show(uvf_reference(texelFetch(u_gbuffer_uv, px, 0).xy), p, n, tangent, rd);
        colour = u_uvf_view == UVF_VIEW_ERROR ? abs(colour - r) * u_uvf_error_scale : r;
    }
    if (uvf_edge(px)) colour = mix(colour, vec3(1.0, 0.55, 0.1), 0.8);
    frag_color = vec4(colour, 1.0);
}
