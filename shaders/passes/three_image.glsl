// The fragment stage of a network drawn as an image by a three.js ShaderMaterial (inshade
// export-three): the network at the mesh's uv, its colour in linear light (decoded where the network
// gives sRGB), then three's tone mapping and output colour space, as its own materials end
// (tonemapping_fragment, colorspace_fragment: three's prefix declares toneMapping() and
// linearToOutputTexel()).
//
// Defines (written at the top): FIELD_OUT_OFFSET, FIELD_OUT_DIM, FIELD_OUT_SRGB (lib/field_output).
#include <lib/field_output>
#include <lib/colour>

in vec2 v_inshade_uv;
layout(location = 0) out highp vec4 inshade_colour;   // GLSL 3 materials declare their own output

void main() {
    vec4 x[NET_IN_BLOCKS];
    x[0] = vec4(v_inshade_uv, 0.0, 0.0);
    vec4 y[NET_OUT_BLOCKS];
    net_eval(x, y);
    vec3 rgb = field_rgb(y);
#ifdef FIELD_OUT_SRGB
    rgb = srgb_eotf(clamp(rgb, 0.0, 1.0));
#endif
#if FIELD_OUT_DIM == 4
    inshade_colour = vec4(rgb, clamp(field_lane(y, FIELD_OUT_OFFSET + 3), 0.0, 1.0));
#else
    inshade_colour = vec4(rgb, 1.0);
#endif
#if defined(TONE_MAPPING)
    inshade_colour.rgb = toneMapping(inshade_colour.rgb);
#endif
    inshade_colour = linearToOutputTexel(inshade_colour);
}
