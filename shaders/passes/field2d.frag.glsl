// 2D field pass: evaluates the generated network (one 2-wide input, the uv) once per pixel and
// writes its colour output, in linear light, to a float target (RGBA32F).
//
// Orientation, decided once for every 2D field (every torch twin of a field follows it): uv (0,0) is
// the bottom-left corner of the picture and (1,1) the top-right, the GL texture convention
// (y up). Each pixel is evaluated at its centre, uv = gl_FragCoord.xy / u_size, which is what
// fullscreen.vert's v_uv interpolates to; it is computed from gl_FragCoord rather than read from
// v_uv because the interpolated value may be an ulp off, and a high-frequency network turns that
// into visible disagreement with torch. render.read_rgba flips rows, so image row 0 (top) holds
// v = (H - 0.5) / H.
//
// Camera (scene/camera.py, `plane2d`): uv = u_view.xy + gl_FragCoord.xy / u_size * u_view.zw. The
// default view is u_view = (0, 0, 1, 1), which adds 0 and multiplies by 1 (exact), so the pixels
// are the same as without a camera. Outside the unit square the network is not evaluated and the
// pixel is transparent (alpha 0 = no coverage; the display pass draws a background there).
//
// Defines (set by runtime/headless.py from the bundle's `render` field):
//   FIELD_OUT_OFFSET  first lane of the shown output in the network's concatenated outputs
//   FIELD_OUT_DIM     its width: 1 (grey), 3 (rgb, alpha = 1) or 4 (rgba)
//   FIELD_OUT_SRGB    defined when the output's semantic is "srgb": its colour is sRGB-encoded (a
//                     network fitted to sRGB pixels) and is decoded to linear here, as textures are
#include <lib/field_output>
#include <lib/colour>

#if NET_IN_DIM != 2
#error "passes/field2d.frag needs a network with one 2-wide input (uv)"
#endif

uniform vec2 u_size;  // target size in pixels
uniform vec4 u_view;  // camera: uv offset (xy) and uv extent of the target (zw)
layout(location = 0) out vec4 frag_color;

void main() {
    vec2 uv = u_view.xy + (gl_FragCoord.xy / u_size) * u_view.zw;
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) {
        frag_color = vec4(0.0);
        return;
    }
    vec4 x[NET_IN_BLOCKS];
    x[0] = vec4(uv, 0.0, 0.0);
    vec4 y[NET_OUT_BLOCKS];
    net_eval(x, y);
#if FIELD_OUT_DIM == 1 || FIELD_OUT_DIM == 3
    frag_color = vec4(field_rgb(y), 1.0);
#else
    frag_color = vec4(field_rgb(y), field_lane(y, FIELD_OUT_OFFSET + 3));
#endif
#ifdef FIELD_OUT_SRGB
    frag_color.rgb = srgb_eotf(clamp(frag_color.rgb, 0.0, 1.0));
#endif
}
