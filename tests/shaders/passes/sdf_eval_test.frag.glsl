// Test pass for the generated <sdf_scene>: one point per pixel (texel (x, y) of u_points, data
// orientation) -> attachment 0: (scene_sdf, 0, 0, 1), attachment 1: (scene_albedo, 1),
// attachment 2: (sdf_normal, 1). Used by tests/geometry/test_sdf.py.
#include <lib/sdf>

uniform sampler2D u_points;
layout(location = 0) out vec4 out_distance;
layout(location = 1) out vec4 out_albedo;
layout(location = 2) out vec4 out_normal;

void main() {
    vec3 p = texelFetch(u_points, ivec2(gl_FragCoord.xy), 0).xyz;
    out_distance = vec4(scene_sdf(p), 0.0, 0.0, 1.0);
    out_albedo = vec4(scene_albedo(p), 1.0);
    out_normal = vec4(sdf_normal(p), 1.0);
}
