// eval.wgsl for a network with uint inputs (WGSL has no preprocessor): the uint lanes of element i are
// blocks [i * NET_IN_UINT_BLOCKS, (i + 1) * NET_IN_UINT_BLOCKS) of inshade_xu.
@group(1) @binding(0) var<storage, read> inshade_x: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> inshade_y: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read> inshade_xu: array<vec4<u32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * 65535u * 64u;
    // the batch is as long as every buffer says (an unread buffer keeps its binding)
    if (i >= arrayLength(&inshade_y) / u32(NET_OUT_BLOCKS) || i >= arrayLength(&inshade_x) / u32(NET_IN_BLOCKS)
        || i >= arrayLength(&inshade_xu) / u32(NET_IN_UINT_BLOCKS)) {
        return;
    }
    var x: array<vec4<f32>, NET_IN_BLOCKS>;
    for (var b: i32 = 0; b < NET_IN_BLOCKS; b++) { x[b] = inshade_x[i * u32(NET_IN_BLOCKS) + u32(b)]; }
    var xu: array<vec4<u32>, NET_IN_UINT_BLOCKS>;
    for (var b: i32 = 0; b < NET_IN_UINT_BLOCKS; b++) { xu[b] = inshade_xu[i * u32(NET_IN_UINT_BLOCKS) + u32(b)]; }
    let y = net_eval(xu, x);
    for (var b: i32 = 0; b < NET_OUT_BLOCKS; b++) { inshade_y[i * u32(NET_OUT_BLOCKS) + u32(b)] = y[b]; }
}
