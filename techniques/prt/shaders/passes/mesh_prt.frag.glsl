// Mesh PRT pass (Learnt Transfer, Dhawal et al. 2022 4.1, deferred): the mesh was rasterised once with depth testing into a
// G-buffer (runtime/geometry.py MeshGBuffer, passes/mesh_gbuffer.frag: world position with w = 1
// where covered, unit normal), so this full-screen pass runs the transfer network exactly once per
// visible pixel, then PRT shading (lib/prt) as the SDF pass does; uncovered pixels show the
// band-limited environment max(L(rd), 0). Linear radiance, alpha 1.
// Debug u_prt_debug as passes/sdf_prt.frag (1..4 transfer block, 5 position, 6 normal).
// Torch reference: techniques/prt/twin.py render_gbuffer() (fed the same G-buffer).
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/prt>
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
    vec3 p, n;
    bool covered = gbuffer_surface(ivec2(gl_FragCoord.xy), p, n);
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    if (!covered) {
        frag_color = u_prt_debug > 0 ? vec4(0.0) : vec4(sh_background(rd, u_sh), 1.0);
        return;
    }
    vec4 tr[PRT_BLOCKS];
    prt_transfer(p, n, tr);
    if (u_prt_debug > 0) {
        frag_color = prt_debug(u_prt_debug, tr, p, n);
        return;
    }
    vec3 albedo = MESH_ALBEDO * u_albedo;
    frag_color = vec4(prt_shade(tr, albedo, n, rd, u_sh, u_shading, u_phong_exponent, u_kd, u_ks), 1.0);
}
