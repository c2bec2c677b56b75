// The fragment stage of an SDF drawn by a three.js ShaderMaterial (inshade export-three): the view ray
// through the fragment, sphere traced as passes/sdf_diffuse.frag traces it (lib/sdf's sdf_hit: the
// same march, hit test and normal taps), shaded as it shades a hit (albedo * E(n) / pi under the SH
// environment u_sh); a miss leaves three's background. Then three's tone mapping and output colour
// space, as its own materials end (three_image.glsl).
#include <lib/sdf>
#include <lib/spherical_harmonics>

uniform vec3 u_sh[SH_COEFFS];
in vec3 v_inshade_ro;
in vec3 v_inshade_p;
layout(location = 0) out highp vec4 inshade_colour;   // GLSL 3 materials declare their own output

const float SDF_INV_PI = 0.318309873;  // float32(1 / pi), as passes/sdf_diffuse.frag

void main() {
    vec3 ro = v_inshade_ro;
    vec3 rd = normalize(v_inshade_p - ro);
    float t;
    vec3 n;
    if (!sdf_hit(ro, rd, t, n)) {
        discard;
    }
    vec3 p = ro + rd * t;
    inshade_colour = vec4(scene_albedo(p) * sh_irradiance(n, u_sh) * SDF_INV_PI, 1.0);
#if defined(TONE_MAPPING)
    inshade_colour.rgb = toneMapping(inshade_colour.rgb);
#endif
    inshade_colour = linearToOutputTexel(inshade_colour);
}
