// A network as a Shadertoy Image pass: mainImage draws its colour over the unit square, fitted and
// centred in the view. uv (0,0) is the square's bottom-left corner and each pixel is evaluated at
// its centre, as passes/field2d.frag does: on a square view the network sees the very uvs
// `inshade render` gives it. Shadertoy shows fragColor as sRGB-encoded values, so a linear output
// is encoded here and an sRGB one is shown as the network gives it.
//
// Defines (written at the top of the pasted pass):
//   FIELD_OUT_OFFSET, FIELD_OUT_DIM   the shown output's lanes (lib/field_output)
//   FIELD_OUT_SRGB                    defined when its values are sRGB-encoded already
#include <lib/field_output>
#include <lib/colour>

const vec3 SHADERTOY_BACKGROUND = vec3(0.18);

// The network's colour at uv in its own space: rgb, and alpha (1 for a grey or rgb output).
vec4 shadertoy_colour(vec2 uv) {
    vec4 x[NET_IN_BLOCKS];
    x[0] = vec4(uv, 0.0, 0.0);
    vec4 y[NET_OUT_BLOCKS];
    net_eval(x, y);
#if FIELD_OUT_DIM == 4
    return vec4(field_rgb(y), field_lane(y, FIELD_OUT_OFFSET + 3));
#else
    return vec4(field_rgb(y), 1.0);
#endif
}

void mainImage(out vec4 fragColor, in vec2 fragCoord) {
    float side = min(iResolution.x, iResolution.y);
    vec2 uv = (fragCoord - 0.5 * (iResolution.xy - side)) / side;
    vec3 shown = SHADERTOY_BACKGROUND;
    if (all(greaterThanEqual(uv, vec2(0.0))) && all(lessThanEqual(uv, vec2(1.0)))) {
        vec4 c = shadertoy_colour(uv);
        vec3 rgb = clamp(c.rgb, 0.0, 1.0);
#ifndef FIELD_OUT_SRGB
        rgb = srgb_oetf(rgb);
#endif
        shown = mix(shown, rgb, clamp(c.a, 0.0, 1.0));
    }
    fragColor = vec4(shown, 1.0);
}
