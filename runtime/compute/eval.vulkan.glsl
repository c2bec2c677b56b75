// Evaluates the network once per invocation (set 1: the batch; set 0: the network's resources).
layout(local_size_x = 64) in;
layout(std430, set = 1, binding = 0) readonly buffer InshadeX { vec4 inshade_x[]; };
layout(std430, set = 1, binding = 1) buffer InshadeY { vec4 inshade_y[]; };
#ifdef NET_IN_UINT_BLOCKS
layout(std430, set = 1, binding = 2) readonly buffer InshadeXU { uvec4 inshade_xu[]; };
#endif

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * 65535u * 64u;
    // the batch is as long as both buffers say: the inputs' length keeps their binding in the shader
    // even for a network that reads none of them (a compiler drops an unread buffer, which the host binds)
    if (i >= uint(inshade_y.length()) / uint(NET_OUT_BLOCKS) || i >= uint(inshade_x.length()) / uint(NET_IN_BLOCKS)) return;
    vec4 x[NET_IN_BLOCKS];
    vec4 y[NET_OUT_BLOCKS];
    for (int b = 0; b < NET_IN_BLOCKS; ++b) x[b] = inshade_x[i * uint(NET_IN_BLOCKS) + uint(b)];
#ifdef NET_IN_UINT_BLOCKS
    uvec4 xu[NET_IN_UINT_BLOCKS];
    for (int b = 0; b < NET_IN_UINT_BLOCKS; ++b) xu[b] = inshade_xu[i * uint(NET_IN_UINT_BLOCKS) + uint(b)];
    net_eval(xu, x, y);
#else
    net_eval(x, y);
#endif
    for (int b = 0; b < NET_OUT_BLOCKS; ++b) inshade_y[i * uint(NET_OUT_BLOCKS) + uint(b)] = y[b];
}
