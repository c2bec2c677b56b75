// instant-NGP's radiance field in a fragment shader: a hash-grid field (network hgrf) ray marched
// through its box with the occupancy grid (network hgocc) stepping over empty cells
// (lib/radiance_field_march). u_hgrf_view (HGRF_VIEW_* from <choices>):
//   radiance   the composited radiance (linear RGB over the background, alpha 1);
//   reference  the held-out ground truth at the scene's camera (u_hgrf_reference, 8-bit sRGB);
//   split      reference left of u_hgrf_split, radiance right (the edge's pixel column white);
//   error      how far the radiance lies outside the linear values the reference's 8-bit sRGB byte
//              stands for, x u_hgrf_error_scale (the reference's own rounding is not an error);
//   samples    the network evaluations per pixel / 64 (grey: what the occupancy grid saves).
// u_hgrf_empty_space: HGRF_EMPTY_SKIP | HGRF_EMPTY_EVALUATE (every sample, the grid unused).
// The reference is a picture of one camera: away from it, reference, split and error compare views
// of different cameras.
#include <lib/camera>
#include <lib/colour>
#include <network_hgrf>
#include <network_hgocc>
#include <radiance_field_config>
#include <lib/radiance_field_march>
#include <choices>

uniform vec2 u_size;
uniform int u_hgrf_view;
uniform int u_hgrf_empty_space;
uniform float u_hgrf_split;
uniform float u_hgrf_error_scale;
uniform sampler2D u_hgrf_reference;   // scene texture: the ground truth, 8-bit sRGB-encoded
layout(location = 0) out vec4 frag_color;

void main() {
    // the texel under the pixel (the reference's own texel when the target has its size)
    ivec2 texel = ivec2(gl_FragCoord.xy * vec2(textureSize(u_hgrf_reference, 0)) / u_size);
    vec3 encoded = texelFetch(u_hgrf_reference, texel, 0).rgb;
    vec3 reference = srgb_eotf(encoded);
    int view = u_hgrf_view;
    if (view == HGRF_VIEW_SPLIT) {
        float edge = u_hgrf_split * u_size.x;
        if (floor(gl_FragCoord.x) == floor(edge)) {   // the pixel column holding the edge
            frag_color = vec4(1.0);
            return;
        }
        view = gl_FragCoord.x < edge ? HGRF_VIEW_REFERENCE : HGRF_VIEW_RADIANCE;
    }
    if (view == HGRF_VIEW_REFERENCE) {
        frag_color = vec4(reference, 1.0);
        return;
    }
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    int evals;
    vec3 c = hgrf_march(ro, rd, u_hgrf_empty_space == HGRF_EMPTY_SKIP, evals);
    if (view == HGRF_VIEW_SAMPLES) {
        c = vec3(min(float(evals) / 64.0, 1.0));
    } else if (view == HGRF_VIEW_ERROR) {
        vec3 lo = srgb_eotf(max(encoded - 0.5 / 255.0, 0.0));
        vec3 hi = srgb_eotf(min(encoded + 0.5 / 255.0, 1.0));
        c = max(max(lo - c, c - hi), 0.0) * u_hgrf_error_scale;
    }
    frag_color = vec4(c, 1.0);
}
