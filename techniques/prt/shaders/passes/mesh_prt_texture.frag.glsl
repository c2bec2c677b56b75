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
#include <lib/prt_pass>
#include <choices>

layout(location = 0) out vec4 frag_color;

void main() {
    vec3 rd, p, n;
    if (gbuffer_pixel(u_size, rd, p, n)) {
        vec4 tr[PRT_BLOCKS];
        prt_texture_transfer(texelFetch(u_gbuffer_uv, ivec2(gl_FragCoord.xy), 0).xy, tr);
        frag_color = prt_pixel(tr, PRT_MESH_ALBEDO, p, n, rd);
    } else {
        frag_color = prt_background(rd);
    }
}
