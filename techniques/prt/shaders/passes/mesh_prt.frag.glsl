// Mesh PRT pass (Learnt Transfer, Dhawal et al. 2022 4.1, deferred): the mesh was rasterised once with depth testing into a
// G-buffer (runtime/geometry.py MeshGBuffer, passes/mesh_gbuffer.frag: world position with w = 1
// where covered, unit normal), so this full-screen pass runs the transfer network exactly once per
// visible pixel, then PRT shading (lib/prt) as the SDF pass does; uncovered pixels show the
// band-limited environment max(L(rd), 0). Linear radiance, alpha 1.
// Debug u_prt_debug as passes/sdf_prt.frag (1..4 transfer block, 5 position, 6 normal).
// Torch reference: techniques/prt/twin.py render_gbuffer() (fed the same G-buffer).
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/prt_pass>
#include <choices>

layout(location = 0) out vec4 frag_color;

void main() {
    vec3 rd, p, n;
    if (gbuffer_pixel(u_size, rd, p, n)) {
        frag_color = prt_network_pixel(PRT_MESH_ALBEDO, p, n, rd);
    } else {
        frag_color = prt_background(rd);
    }
}
