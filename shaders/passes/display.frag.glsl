// Display (composite) pass: turns the scene pass's linear float output into what a display mode
// shows, still in linear light (the screen blit or write_png encodes sRGB afterwards).
// Modes are the generated constants of scene/display.py (DisplayMode), switched by a uniform so a
// mode change never recompiles the network program. In DISPLAY_FINAL at exposure 1 the output is
// the network pass's texel unchanged (x * 1.0), so `inshade render` and the viewer agree exactly.
#include <display_modes>
#include <lib/colour>

uniform sampler2D u_network;    // scene pass output, same size as this target (read with texelFetch)
uniform sampler2D u_reference;  // linear reference, LINEAR filtering, clamp to edge
uniform vec2 u_size;            // target size in pixels
uniform vec4 u_ref_view;        // reference uv = u_ref_view.xy + gl_FragCoord.xy / u_size * u_ref_view.zw
uniform int u_mode;             // DISPLAY_*
uniform int u_has_reference;    // 0: the scene has no reference image
uniform float u_split;          // split line, fraction of the width (DISPLAY_SPLIT)
uniform float u_exposure;
uniform float u_error_scale;    // |error| multiplier before the heat map

layout(location = 0) out vec4 frag_color;

// Heat map for t in [0, 1]: black - purple - orange - yellow (an inferno-like ramp), display-encoded.
vec3 heat_map(float t) {
    t = clamp(t, 0.0, 1.0);
    vec3 c0 = vec3(0.0, 0.0, 0.02), c1 = vec3(0.45, 0.05, 0.55), c2 = vec3(0.95, 0.45, 0.1), c3 = vec3(1.0, 1.0, 0.6);
    vec3 c = t < 0.33 ? mix(c0, c1, t / 0.33) : (t < 0.66 ? mix(c1, c2, (t - 0.33) / 0.33) : mix(c2, c3, (t - 0.66) / 0.34));
    return srgb_eotf(c);
}

vec4 background() {
    ivec2 cell = ivec2(gl_FragCoord.xy) / 8;
    return vec4(vec3(((cell.x + cell.y) & 1) == 0 ? 0.010 : 0.025), 1.0);
}

void main() {
    vec4 net = texelFetch(u_network, ivec2(gl_FragCoord.xy), 0);
    vec2 ruv = u_ref_view.xy + (gl_FragCoord.xy / u_size) * u_ref_view.zw;
    float ref_cover = (u_has_reference != 0 && all(greaterThanEqual(ruv, vec2(0.0))) &&
                       all(lessThanEqual(ruv, vec2(1.0)))) ? 1.0 : 0.0;
    vec3 ref = texture(u_reference, ruv).rgb;

    int mode = u_mode;
    float split_x = u_split * u_size.x;
    if (mode == DISPLAY_SPLIT) {
        mode = gl_FragCoord.x < split_x ? DISPLAY_FINAL : DISPLAY_REFERENCE;
    }
    vec4 c;
    if (mode == DISPLAY_FINAL) {
        c = vec4(net.rgb * u_exposure, net.a);
    } else if (mode == DISPLAY_NETWORK) {
        c = net;
    } else if (mode == DISPLAY_REFERENCE) {
        c = vec4(ref * u_exposure, ref_cover);
    } else if (mode == DISPLAY_ERROR) {
        float e = dot(abs(net.rgb - ref), vec3(1.0 / 3.0));
        c = vec4(heat_map(e * u_error_scale), net.a * ref_cover);
    } else {  // DISPLAY_SQUARED_ERROR: data for PSNR, no background
        vec3 d = net.rgb - ref;
        frag_color = vec4(d * d, net.a * ref_cover);
        return;
    }
    if (c.a <= 0.0) {
        c = background();
    }
    if (u_mode == DISPLAY_SPLIT && abs(gl_FragCoord.x - split_x) < 1.0) {
        c = vec4(1.0);
    }
    frag_color = c;
}
