// Mesh PBR-set pass (Differentiable Indirection, Datta et al. 2023 4.2.1): a compressed PBR texture set (the DI bundle, <network>:
// uv -> 8 lanes) on a rasterised, uv-mapped mesh, lit by point lights and the SH environment
// (lib/pbr_set). Deferred like passes/mesh_prt: the G-buffer (runtime/geometry.py) gives position,
// normal, uv and tangent per pixel, so the network runs once per visible pixel.
// u_pbr_view (VIEWS in techniques/di_pbr_set/__init__.py; PBR_VIEW_* from <choices>): uncompressed
// (u_pbr_set0/1: RGBA8 textures of the same lanes, bilinear, repeat) | di (the DI-compressed set) |
// split (side by side: left half uncompressed, right half DI).
// The texture repeats: the network is evaluated at fract(uv), the textures wrap in hardware.
// Torch twin: techniques/di_pbr_set/render.py render_gbuffer (fed the same G-buffer).
#include <network>
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/pbr_set>
#include <choices>

#if NET_IN_DIM != 2 || NET_OUT_DIM < 8
#error "passes/mesh_pbr_set.frag needs a uv -> 8-lane network (techniques/di_pbr_set/train.py)"
#endif

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform sampler2D u_pbr_set0;   // lanes 0-3
uniform sampler2D u_pbr_set1;   // lanes 4-7
uniform int u_pbr_view;
uniform int u_light_count;
layout(location = 0) out vec4 frag_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 rd, p, n;
    if (!gbuffer_pixel(u_size, rd, p, n)) {
        frag_color = vec4(sh_background(rd, u_sh), 1.0);
        return;
    }
    vec2 uv = fract(texelFetch(u_gbuffer_uv, px, 0).xy);
    bool compressed = u_pbr_view == PBR_VIEW_DI || (u_pbr_view == PBR_VIEW_SPLIT && gl_FragCoord.x >= 0.5 * u_size.x);
    vec4 a, b;
    if (compressed) {
        vec4 x[NET_IN_BLOCKS];
        x[0] = vec4(uv, 0.0, 0.0);
        vec4 y[NET_OUT_BLOCKS];
        net_eval(x, y);
        a = y[0];
        b = y[1];
    } else {
        a = texture(u_pbr_set0, uv);
        b = texture(u_pbr_set1, uv);
    }
    vec4 tangent = texelFetch(u_gbuffer_tangent, px, 0);
    frag_color = vec4(pbr_shade(pbr_set_unpack(a, b), p, n, tangent, rd, u_sh, u_light_count), 1.0);
}
