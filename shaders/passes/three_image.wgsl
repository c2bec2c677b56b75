fn inshade_image(uv: vec2<f32>/*net_textures*/) -> vec4<f32> {
    // The network at the mesh's uv as linear colour and alpha, for a three.js node material (inshade
    // export-three): three_image.glsl's steps; FIELD_OUT_* are constants beside the network's code.
    var x: array<vec4<f32>, NET_IN_BLOCKS>;
    x[0] = vec4<f32>(uv, 0.0, 0.0);
    let y = net_eval(x/*net_texture_names*/);
    var c = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    for (var k: i32 = 0; k < FIELD_OUT_DIM; k++) {
        let lane = FIELD_OUT_OFFSET + k;
        c[k] = y[lane / 4][lane % 4];
    }
    if (FIELD_OUT_DIM == 1) {
        c = vec4<f32>(c.xxx, 1.0);
    }
    if (FIELD_OUT_SRGB) {
        c = vec4<f32>(srgb_eotf(clamp(c.rgb, vec3<f32>(0.0), vec3<f32>(1.0))), c.a);
    }
    return vec4<f32>(c.rgb, clamp(c.a, 0.0, 1.0));
}
