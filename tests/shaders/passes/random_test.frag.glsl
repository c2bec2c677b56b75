// Test pass for lib/random (tests/runtime/test_accumulation.py): pixel (x, y) -> attachment 0:
// random_uniform4(pixel, u_sample_index, u_stream); attachment 1: (random_uniform, the .y of
// random_uniform2, the .z of random_uniform3, 0) with the same arguments (each must equal the
// matching component of attachment 0). The pixel is offset by u_pixel_offset (large coordinates).

#include <lib/random>

uniform int u_sample_index;
uniform int u_stream;
uniform ivec2 u_pixel_offset;
layout(location = 0) out vec4 out_vec4;
layout(location = 1) out vec4 out_narrow;

void main() {
    uvec2 px = uvec2(ivec2(gl_FragCoord.xy) + u_pixel_offset);
    out_vec4 = random_uniform4(px, u_sample_index, u_stream);
    out_narrow = vec4(random_uniform(px, u_sample_index, u_stream), random_uniform2(px, u_sample_index, u_stream).y,
                      random_uniform3(px, u_sample_index, u_stream).z, 0.0);
}
