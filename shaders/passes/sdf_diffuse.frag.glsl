// SDF diffuse pass: full-screen sphere tracing of an analytic scene (lib/sdf + the generated
// <sdf_scene>), lit by an environment given as radiance SH coefficients u_sh (projected and
// rotated on the CPU: codegen/sdf.py environment_sh). Hit: albedo * E(n) / pi with
// E = sh_irradiance (Lambert-convolved SH); miss: the band-limited environment max(L(rd), 0).
// Linear radiance, alpha 1 (exposure is applied by the display pass). No transfer (occlusion)
// yet: the transfer network replaces sh_irradiance(n, u_sh) with dot(transfer(p, n), u_sh).
// Torch reference: models/sdf.py render().
#include <lib/sdf>
#include <lib/spherical_harmonics>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
layout(location = 0) out vec4 frag_color;

const float SDF_INV_PI = 0.318309873;  // float32(1 / pi), as models/sdf.py INV_PI

void main() {
    vec3 rd, p, n;
    if (sdf_pixel(u_size, rd, p, n)) {
        frag_color = vec4(scene_albedo(p) * sh_irradiance(n, u_sh) * SDF_INV_PI, 1.0);
    } else {
        frag_color = vec4(sh_background(rd, u_sh), 1.0);
    }
}
