// A voxel radiance field, ray marched (lib/rf_march) through either the uncompressed grids
// (network rfg: 3D textures, trilinear) or their DI compression (network rfd: primary -> cascaded
// 3D lookups per head). u_rf_view (VIEWS in techniques/di_radiance_field/__init__.py; RF_VIEW_* from
// <choices>): uncompressed | di | split (uncompressed left of u_rf_split, DI right, the edge's pixel column white) |
// error (|di - uncompressed| x u_rf_error_scale). Linear RGB over the constant background, alpha 1.
#include <lib/camera>
#include <network_rfg>
#include <network_rfd>
#include <rf_config>
#include <lib/rf_march>
#include <choices>

uniform vec2 u_size;
uniform int u_rf_view;
uniform float u_rf_split;
uniform float u_rf_error_scale;
layout(location = 0) out vec4 frag_color;

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    int first = u_rf_view == RF_VIEW_DI ? 1 : 0;
    int count = u_rf_view == RF_VIEW_ERROR ? 2 : 1;
    if (u_rf_view == RF_VIEW_SPLIT) {
        float edge = u_rf_split * u_size.x;
        if (floor(gl_FragCoord.x) == floor(edge)) {   // the pixel column holding the edge
            frag_color = vec4(1.0);
            return;
        }
        first = gl_FragCoord.x < edge ? 0 : 1;
    }
    // one call site in a loop the compiler cannot unroll: the networks are inlined into rf_march,
    // and a second call site would double the program (llvmpipe compile time)
    vec4 res[2] = vec4[2](vec4(0.0), vec4(0.0));
    for (int k = 0; k < count; ++k) {
        res[k] = rf_march(first + k, ro, rd);
    }
    frag_color = u_rf_view == RF_VIEW_ERROR ? vec4(abs(res[1].rgb - res[0].rgb) * u_rf_error_scale, 1.0) : res[0];
}
