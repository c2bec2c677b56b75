// Texture-space PRT mesh pass (the paper's baseline, Learnt Transfer, Dhawal et al. 2022 5.1): deferred
// as passes/mesh_prt.frag (runtime/geometry.py MeshGBuffer: world position with w = 1 where covered,
// unit normal, uv), the transfer read from the baked texture at the pixel's uv (lib/prt_texture)
// instead of a network, then the same PRT shading (lib/prt); uncovered pixels show the band-limited
// environment max(L(rd), 0). Linear radiance, alpha 1.
// Debug u_prt_debug as passes/mesh_prt.frag (1..4 transfer block, 5 position, 6 normal).
// Torch reference: techniques/prt/texture_prt.py render_gbuffer_texture() (fed the same G-buffer).
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/prt_texture>
#include <choices>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_shading;          // PRT_DIFFUSE | PRT_GLOSSY
uniform float u_phong_exponent;
uniform float u_albedo;         // tint of the mesh's base colour
uniform float u_kd;
uniform float u_ks;
uniform int u_prt_debug;
layout(location = 0) out vec4 frag_color;

const vec3 MESH_ALBEDO = vec3(0.8);  // the mesh's base colour (techniques/prt/twin.py MESH_ALBEDO)

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 p, n;
    bool covered = gbuffer_surface(px, p, n);
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    if (!covered) {
        frag_color = u_prt_debug > 0 ? vec4(0.0) : vec4(sh_background(rd, u_sh), 1.0);
        return;
    }
    vec4 tr[PRT_BLOCKS];
    prt_texture_transfer(texelFetch(u_gbuffer_uv, px, 0).xy, tr);
    if (u_prt_debug > 0) {
        frag_color = prt_debug(u_prt_debug, tr, p, n);
        return;
    }
    vec3 albedo = MESH_ALBEDO * u_albedo;
    frag_color = vec4(prt_shade(tr, albedo, n, rd, u_sh, u_shading, u_phong_exponent, u_kd, u_ks), 1.0);
}
