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
#include <lib/prt>
#include <choices>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_shading;          // PRT_DIFFUSE | PRT_GLOSSY
uniform float u_phong_exponent;
uniform float u_albedo;         // tint: scales the scene's albedo
uniform float u_kd;
uniform float u_ks;
uniform int u_prt_debug;
layout(location = 0) out vec4 frag_color;

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    float t;
    vec3 n;
    if (sdf_hit(ro, rd, t, n)) {
        vec3 p = ro + rd * t;
        vec4 tr[PRT_BLOCKS];
        prt_transfer(p, n, tr);
        if (u_prt_debug > 0) {
            frag_color = prt_debug(u_prt_debug, tr, p, n);
            return;
        }
        vec3 albedo = scene_albedo(p) * u_albedo;
        frag_color = vec4(prt_shade(tr, albedo, n, rd, u_sh, u_shading, u_phong_exponent, u_kd, u_ks), 1.0);
    } else if (u_prt_debug > 0) {
        frag_color = vec4(0.0);
    } else {
        frag_color = vec4(sh_background(rd, u_sh), 1.0);
    }
}
