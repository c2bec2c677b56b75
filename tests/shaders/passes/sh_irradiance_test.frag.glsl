// Test pass for lib/spherical_harmonics: one unit direction per pixel (texel (x, y) of
// u_dirs, data orientation) -> attachment 0: sh_irradiance, 1: sh_radiance,
// 2: sh_convolved with u_bands, 3: sh_background. Needs chunks=sh_chunks(degree). Used by
// tests/components/test_spherical_harmonics.py.
#include <lib/spherical_harmonics>

uniform sampler2D u_dirs;
uniform vec3 u_sh[SH_COEFFS];
uniform float u_bands[SH_DEGREE];
layout(location = 0) out vec4 out_irradiance;
layout(location = 1) out vec4 out_radiance;
layout(location = 2) out vec4 out_convolved;
layout(location = 3) out vec4 out_background;

void main() {
    vec3 d = texelFetch(u_dirs, ivec2(gl_FragCoord.xy), 0).xyz;
    out_irradiance = vec4(sh_irradiance(d, u_sh), 1.0);
    out_radiance = vec4(sh_radiance(d, u_sh), 1.0);
    out_convolved = vec4(sh_convolved(d, u_sh, u_bands), 1.0);
    out_background = vec4(sh_background(d, u_sh), 1.0);
}
