// lib/prt.glsl's learnt transfer network, absent: the texture-space PRT pass takes its transfer
// from a texture (lib/prt_texture.glsl) and uses lib/prt.glsl for shading only, never calling
// prt_transfer. The same names as a network chunk, no network (techniques/prt/texture_codegen.py
// points the <prt_network> chunk here).
#define PRT_NET_EVAL prt_no_network
#define PRT_NET_IN_BLOCKS 2
#define PRT_NET_OUT_BLOCKS 4
#define PRT_CENTER vec3(0.0)
#define PRT_INV_RADIUS 1.0
#define PRT_SCALE 1.0

void prt_no_network(in vec4 x[2], out vec4 y[PRT_NET_OUT_BLOCKS]) {
    for (int b = 0; b < PRT_NET_OUT_BLOCKS; ++b) {
        y[b] = vec4(0.0);
    }
}
