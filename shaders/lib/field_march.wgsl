// field_march.glsl in WGSL: the same box, steps, order and stop (float32). The network (net_eval)
// maps (position, direction) to rgb and density; the FIELD_* constants are codegen/field.py's. The
// /*net_...*/ slots take a network's textures where it takes them as arguments (thread_textures).

// The box's entry t0 >= 0 and exit t1 along the ray: (t0, t1), a miss where t1 < t0.
fn field_box(ro: vec3<f32>, rd: vec3<f32>) -> vec2<f32> {
    let d = select(rd, vec3<f32>(1e-12), abs(rd) < vec3<f32>(1e-12));
    let inv = 1.0 / d;
    let a = (FIELD_BOX_LO - ro) * inv;
    let c = (FIELD_BOX_HI - ro) * inv;
    let lo = min(a, c);
    let hi = max(a, c);
    return vec2<f32>(max(max(lo.x, lo.y), max(lo.z, 0.0)), min(hi.x, min(hi.y, hi.z)));
}

// The radiance C gathered along the ray (rgb) and the transmittance T left (w).
fn field_march_parts(ro: vec3<f32>, rd: vec3<f32>/*net_textures*/) -> vec4<f32> {
    var colour = vec3<f32>(0.0);
    var trans = 1.0;
    let span = field_box(ro, rd);
    if (span.y < span.x) {
        return vec4<f32>(colour, trans);
    }
    for (var i: i32 = 0; i < FIELD_MAX_STEPS; i++) {
        let t = span.x + (f32(i) + 0.5) * FIELD_STEP;
        if (t >= span.y) {
            break;
        }
        let p = ro + rd * t;
        var x: array<vec4<f32>, NET_IN_BLOCKS>;
        x[0] = vec4<f32>(p, rd.x);
        x[1] = vec4<f32>(rd.yz, 0.0, 0.0);
        let y = net_eval(x/*net_texture_names*/);
        let sigma = max(y[0].w, 0.0);
        let alpha = 1.0 - exp(-sigma * FIELD_STEP);
        colour += (trans * alpha) * y[0].rgb;
        trans = trans * (1.0 - alpha);
        if (trans < FIELD_STOP) {
            break;
        }
    }
    return vec4<f32>(colour, trans);
}
