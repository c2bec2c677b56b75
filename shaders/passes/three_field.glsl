// The fragment stage of a radiance field drawn by a three.js ShaderMaterial (inshade export-three): the
// view ray through the fragment, marched through the field's box as passes/imported_field.frag marches
// it (lib/field_march: the same steps and stop), its radiance C and coverage 1 - T written
// premultiplied, so the material (premultipliedAlpha) lays the field over whatever three drew behind
// it; over black, the pixels inshade render draws over a black background. Then three's tone mapping
// and output colour space, as its own materials end (three_image.glsl).
#include <network>
#include <field_config>
#include <lib/field_march>

in vec3 v_inshade_ro;
in vec3 v_inshade_p;
layout(location = 0) out highp vec4 inshade_colour;   // GLSL 3 materials declare their own output

void main() {
    vec3 ro = v_inshade_ro;
    vec3 rd = normalize(v_inshade_p - ro);
    vec3 colour;
    float trans = field_march_parts(ro, rd, colour);
    inshade_colour = vec4(colour, 1.0 - trans);
#if defined(TONE_MAPPING)
    inshade_colour.rgb = toneMapping(inshade_colour.rgb);
#endif
    inshade_colour = linearToOutputTexel(inshade_colour);
}
