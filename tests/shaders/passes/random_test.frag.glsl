// Test pass for lib/random (tests/runtime/test_accumulation.py): pixel (x, y) -> attachment 0:
// random_uniform4(pixel, u_sample_index, u_stream); attachment 1: (random_uniform, the .y of
// random_uniform2, the .z of random_uniform3, 0) with the same arguments (each must equal the
// matching component of attachment 0). The pixel is offset by u_pixel_offset (large coordinates).

#include <lib/random>

uniform int u_sample_index;
uniform int u_stream;
uniform ivec2 u_pixel_offset;
layout(location = 0) out vec4 frag_out[2];   // the vec4 draw, then the narrower ones

void main() {
    uvec2 px = uvec2(ivec2(gl_FragCoord.xy) + u_pixel_offset);
    frag_out[0] = random_uniform4(px, u_sample_index, u_stream);
    frag_out[1] = vec4(random_uniform(px, u_sample_index, u_stream), random_uniform2(px, u_sample_index, u_stream).y,
                       random_uniform3(px, u_sample_index, u_stream).z, 0.0);
}
