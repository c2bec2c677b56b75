// SDF PRT pass (Learnt Transfer, Dhawal et al. 2022): full-screen sphere tracing of the scene (lib/sdf + the generated
// <sdf_scene>: an analytic description or a neural SDF), the normal from the SDF gradient, one
// evaluation of the transfer network at the hit (lib/prt) and PRT shading under the environment
// u_sh; misses show the band-limited environment max(L(rd), 0) as sdf_diffuse does. Linear
// radiance, alpha 1 (exposure is applied by the display pass).
// Debug (u_prt_debug, PRT_DEBUG_* in lib/prt): 1..4 write the raw transfer block b = u_prt_debug - 1
// (coefficients 4b..4b+3), 5 the hit position, 6 the normal (w = 1); misses write 0. For parity
// tests (the network checked at the shader's own p, n) and the viewer's transfer inspection.
// Torch reference: techniques/prt/twin.py render().
#include <lib/sdf>
#include <lib/prt_pass>
#include <choices>

layout(location = 0) out vec4 frag_color;

void main() {
    vec3 rd, p, n;
    if (sdf_pixel(u_size, rd, p, n)) {
        frag_color = prt_network_pixel(scene_albedo(p), p, n, rd);
    } else {
        frag_color = prt_background(rd);
    }
}
