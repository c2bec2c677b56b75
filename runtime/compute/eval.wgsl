// Evaluates the network once per invocation: the inputs of element i are blocks
// [i * NET_IN_BLOCKS, (i + 1) * NET_IN_BLOCKS) of inshade_x, its outputs go to inshade_y likewise.
@group(1) @binding(0) var<storage, read> inshade_x: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> inshade_y: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * 65535u * 64u;
    // the batch is as long as both buffers say: the inputs' length keeps their binding in the shader
    // even for a network that reads none of them (a compiler drops an unread buffer, which the host binds)
    if (i >= arrayLength(&inshade_y) / u32(NET_OUT_BLOCKS) || i >= arrayLength(&inshade_x) / u32(NET_IN_BLOCKS)) {
        return;
    }
    var x: array<vec4<f32>, NET_IN_BLOCKS>;
    for (var b: i32 = 0; b < NET_IN_BLOCKS; b++) { x[b] = inshade_x[i * u32(NET_IN_BLOCKS) + u32(b)]; }
    let y = net_eval(x);
    for (var b: i32 = 0; b < NET_OUT_BLOCKS; b++) { inshade_y[i * u32(NET_OUT_BLOCKS) + u32(b)] = y[b]; }
}
