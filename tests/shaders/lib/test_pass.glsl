// What a test pass reads (tests/parity.py run_sample_pass lays it out): one sample per pixel, made of
// TEST_TEXELS texels side by side in u_inputs (data orientation). A pass with wider samples defines
// TEST_TEXELS before including this chunk.
#ifndef TEST_TEXELS
#define TEST_TEXELS 1
#endif

uniform sampler2D u_inputs;

// Texel i (0 .. TEST_TEXELS - 1) of this pixel's sample.
vec4 test_input(int i) {
    ivec2 p = ivec2(gl_FragCoord.xy);
    return texelFetch(u_inputs, ivec2(p.x * TEST_TEXELS + i, p.y), 0);
}

// Every texel of this pixel's sample.
void test_inputs(out vec4 t[TEST_TEXELS]) {
    for (int i = 0; i < TEST_TEXELS; ++i) t[i] = test_input(i);
}
