// Evaluates the generated network chunk once per pixel: the parity harness and `inshade bench`.
// Inputs: NET_IN_BLOCKS texels per sample, side by side in a float texture (data orientation);
// a network with uint inputs also gets NET_IN_UINT_BLOCKS texels per sample of an RGBA32UI texture.
// Outputs: block b of the result goes to colour attachment b (RGBA32F). A target with fewer draw
// buffers than blocks takes them in passes: EVAL_OUT_FIRST is the first block this pass writes,
// EVAL_OUT_TARGETS how many (WebGL2 guarantees 4 draw buffers).
#include <network>
#ifndef EVAL_OUT_FIRST
#define EVAL_OUT_FIRST 0
#endif
#ifndef EVAL_OUT_TARGETS
#define EVAL_OUT_TARGETS NET_OUT_BLOCKS
#endif

uniform sampler2D u_inputs;
#ifdef NET_IN_UINT_DIM
uniform usampler2D u_inputs_uint;
#endif
layout(location = 0) out vec4 frag_out[EVAL_OUT_TARGETS];

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 x[NET_IN_BLOCKS];
    for (int b = 0; b < NET_IN_BLOCKS; ++b) {
        x[b] = texelFetch(u_inputs, ivec2(p.x * NET_IN_BLOCKS + b, p.y), 0);
    }
    vec4 y[NET_OUT_BLOCKS];
#ifdef NET_IN_UINT_DIM
    uvec4 xu[NET_IN_UINT_BLOCKS];
    for (int b = 0; b < NET_IN_UINT_BLOCKS; ++b) {
        xu[b] = texelFetch(u_inputs_uint, ivec2(p.x * NET_IN_UINT_BLOCKS + b, p.y), 0);
    }
    net_eval(xu, x, y);
#else
    net_eval(x, y);
#endif
    // ES 3.00 indexes fragment outputs with constants only.
    frag_out[0] = y[EVAL_OUT_FIRST];
#if EVAL_OUT_TARGETS > 1
    frag_out[1] = y[EVAL_OUT_FIRST + 1];
#endif
#if EVAL_OUT_TARGETS > 2
    frag_out[2] = y[EVAL_OUT_FIRST + 2];
#endif
#if EVAL_OUT_TARGETS > 3
    frag_out[3] = y[EVAL_OUT_FIRST + 3];
#endif
#if EVAL_OUT_TARGETS > 4
    frag_out[4] = y[EVAL_OUT_FIRST + 4];
#endif
#if EVAL_OUT_TARGETS > 5
    frag_out[5] = y[EVAL_OUT_FIRST + 5];
#endif
#if EVAL_OUT_TARGETS > 6
    frag_out[6] = y[EVAL_OUT_FIRST + 6];
#endif
#if EVAL_OUT_TARGETS > 7
    frag_out[7] = y[EVAL_OUT_FIRST + 7];
#endif
}
