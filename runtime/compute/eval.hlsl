// Evaluates the network once per invocation (space 1: the batch; space 0: the network's resources).
[[vk::binding(0, 1)]] StructuredBuffer<float4> inshade_x : register(t0, space1);
[[vk::binding(1, 1)]] RWStructuredBuffer<float4> inshade_y : register(u0, space1);

[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = id.x + id.y * 65535u * 64u;
    uint count, stride;
    inshade_y.GetDimensions(count, stride);
    if (i >= count / NET_OUT_BLOCKS) return;
    float4 x[NET_IN_BLOCKS];
    float4 y[NET_OUT_BLOCKS];
    for (int b = 0; b < NET_IN_BLOCKS; ++b) x[b] = inshade_x[i * NET_IN_BLOCKS + b];
    net_eval(x, y);
    for (int b = 0; b < NET_OUT_BLOCKS; ++b) inshade_y[i * NET_OUT_BLOCKS + b] = y[b];
}
