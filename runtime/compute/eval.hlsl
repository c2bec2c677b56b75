// Evaluates the network once per invocation (space 1: the batch; space 0: the network's resources).
// EVAL_FUNCTION: what is evaluated (the network's net_eval, or an engine drop-in's check adapter).
#ifndef EVAL_FUNCTION
#define EVAL_FUNCTION net_eval
#define EVAL_IN_BLOCKS NET_IN_BLOCKS
#define EVAL_OUT_BLOCKS NET_OUT_BLOCKS
#endif
[[vk::binding(0, 1)]] StructuredBuffer<float4> inshade_x : register(t0, space1);
[[vk::binding(1, 1)]] RWStructuredBuffer<float4> inshade_y : register(u0, space1);
#ifdef NET_IN_UINT_BLOCKS
[[vk::binding(2, 1)]] StructuredBuffer<uint4> inshade_xu : register(t1, space1);
#endif

[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = id.x + id.y * 65535u * 64u;
    // the batch is as long as both buffers say: the inputs' length keeps their binding in the shader
    // even for a network that reads none of them (a compiler drops an unread buffer, which the host binds)
    uint count, stride, in_count;
    inshade_y.GetDimensions(count, stride);
    inshade_x.GetDimensions(in_count, stride);
    if (i >= count / EVAL_OUT_BLOCKS || i >= in_count / EVAL_IN_BLOCKS) return;
    float4 x[EVAL_IN_BLOCKS];
    float4 y[EVAL_OUT_BLOCKS];
    for (int b = 0; b < EVAL_IN_BLOCKS; ++b) x[b] = inshade_x[i * EVAL_IN_BLOCKS + b];
#ifdef NET_IN_UINT_BLOCKS
    uint4 xu[NET_IN_UINT_BLOCKS];
    for (int c = 0; c < NET_IN_UINT_BLOCKS; ++c) xu[c] = inshade_xu[i * NET_IN_UINT_BLOCKS + c];
    net_eval(xu, x, y);
#else
    EVAL_FUNCTION(x, y);
#endif
    for (int b = 0; b < EVAL_OUT_BLOCKS; ++b) inshade_y[i * EVAL_OUT_BLOCKS + b] = y[b];
}
