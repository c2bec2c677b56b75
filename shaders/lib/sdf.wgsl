// sdf.glsl in WGSL: the same bound span, march, hit test and normal taps (float32), with one call
// site of scene_sdf. The scene (scene_sdf, scene_albedo and the SDF_* constants) is the generated
// chunk sdf_scene (codegen/network_sdf.py), placed before this one. /*net_textures*/ and
// /*net_texture_names*/ are where a network that takes its textures as arguments gets them
// (codegen/printers/wgsl.py thread_textures).

// The ray's span (t, t1) inside the bound sphere; t1 < 0 when it misses the sphere.
fn sdf_bound_span(ro: vec3<f32>, rd: vec3<f32>) -> vec2<f32> {
    let oc = ro - SDF_BOUND_CENTER;
    let b = oc.x * rd.x + oc.y * rd.y + oc.z * rd.z;
    let c = oc.x * oc.x + oc.y * oc.y + oc.z * oc.z - SDF_BOUND_RADIUS * SDF_BOUND_RADIUS;
    let h = b * b - c;
    let sq = sqrt(max(h, 0.0));
    let t1 = -b + sq;
    return vec2<f32>(max(-b - sq, 0.0), select(t1, -1.0, h < 0.0));
}

const SDF_NORMAL_TAPS: i32 = 6;

fn sdf_tap_sign(i: i32) -> f32 {
    return select(-1.0, 1.0, i % 2 == 0);
}

fn sdf_tap_offset(i: i32) -> vec3<f32> {
    var e = vec3<f32>(0.0);
    e[i / 2] = sdf_tap_sign(i) * SDF_NORMAL_EPS;
    return e;
}

// Sphere tracing inside the bound sphere, then the unit normal at the hit (sdf.glsl's sdf_hit):
// true on a hit, with the distance along the ray in *t and the normal in *n.
fn sdf_hit(ro: vec3<f32>, rd: vec3<f32>, t: ptr<function, f32>, n: ptr<function, vec3<f32>>/*net_textures*/) -> bool {
    *n = vec3<f32>(0.0);
    let span = sdf_bound_span(ro, rd);
    *t = span.x;
    let t1 = span.y;
    if (t1 < 0.0) {
        return false;
    }
    var p = vec3<f32>(0.0);
    var g = vec3<f32>(0.0);
    var tap: i32 = -1;  // -1 while marching
    for (var i: i32 = 0; i < SDF_MAX_STEPS + SDF_NORMAL_TAPS; i++) {
        var q: vec3<f32>;
        if (tap < 0) {
            q = ro + rd * *t;
        } else {
            q = p + sdf_tap_offset(tap);
        }
        let d = scene_sdf(q/*net_texture_names*/);
        if (tap >= 0) {
            g[tap / 2] += sdf_tap_sign(tap) * d;
            tap += 1;
            if (tap == SDF_NORMAL_TAPS) {
                *n = g * (1.0 / length(g));
                return true;
            }
        } else if (d < SDF_HIT_EPS) {
            p = q;
            tap = 0;
        } else {
            *t = *t + d * SDF_STEP_SCALE;
            if (*t > t1 || i == SDF_MAX_STEPS - 1) {
                return false;
            }
        }
    }
    return false;
}
