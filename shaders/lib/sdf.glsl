// SDF scenes: sphere tracing and normals (camera rays: lib/camera). The scene itself is the generated
// chunk <sdf_scene> (codegen/sdf.py: chunks=sdf_chunks(scene)): scene_sdf(p), scene_albedo(p) and
// the constants SDF_MAX_STEPS, SDF_STEP_SCALE, SDF_HIT_EPS, SDF_NORMAL_EPS, SDF_BOUND_CENTER,
// SDF_BOUND_RADIUS. Torch twins, step for step, in models/sdf.py (trace, normals).
// World frame: right-handed, y up; the camera looks down -z (scene/camera.py).
#include <sdf_scene>

#include <lib/camera>

// The ray's span [t, t1] inside the bound sphere; false when it misses the sphere.
bool sdf_bound_span(vec3 ro, vec3 rd, out float t, out float t1) {
    vec3 oc = ro - SDF_BOUND_CENTER;
    float b = oc.x * rd.x + oc.y * rd.y + oc.z * rd.z;
    float c = oc.x * oc.x + oc.y * oc.y + oc.z * oc.z - SDF_BOUND_RADIUS * SDF_BOUND_RADIUS;
    float h = b * b - c;
    float sq = sqrt(max(h, 0.0));
    t = max(-b - sq, 0.0);
    t1 = -b + sq;
    return !(h < 0.0 || t1 < 0.0);
}

// The normal's central-difference taps: tap i steps SDF_NORMAL_EPS along axis i / 2, + for even i
// and - for odd, and adds sign * f to that axis of the gradient.
const int SDF_NORMAL_TAPS = 6;

float sdf_tap_sign(int i) {
    return (i % 2 == 0) ? 1.0 : -1.0;
}

vec3 sdf_tap_offset(int i) {
    vec3 e = vec3(0.0);
    e[i / 2] = sdf_tap_sign(i) * SDF_NORMAL_EPS;
    return e;
}

// Sphere tracing inside the bound sphere, then the unit normal at the hit, with one call site of
// scene_sdf: a compiler inlines every call, and a big network inlined once per call takes minutes
// to compile. The march steps d * SDF_STEP_SCALE (< 1: smooth booleans and repetition give a bound,
// not an exact distance), hits when d < SDF_HIT_EPS, gives up past the sphere's exit or after
// SDF_MAX_STEPS; the hit point p = ro + rd * t then takes the SDF_NORMAL_TAPS taps, and
// n = g / |g|. A ray grazing an edge or meeting a surface at a shallow angle crawls (steps shrink by
// about SDF_STEP_SCALE * sin(angle)) and may need ~180 steps; one that runs out is a miss, i.e. a
// sky-coloured hole in the surface: SDF_MAX_STEPS must cover them (geometry/sdf.py, default 256).
bool sdf_hit(vec3 ro, vec3 rd, out float t, out vec3 n) {
    n = vec3(0.0);
    float t1;
    if (!sdf_bound_span(ro, rd, t, t1)) {
        return false;
    }
    vec3 p = vec3(0.0);
    vec3 g = vec3(0.0);
    int tap = -1;  // -1 while marching
    for (int i = 0; i < SDF_MAX_STEPS + SDF_NORMAL_TAPS; ++i) {
        vec3 q = (tap < 0) ? ro + rd * t : p + sdf_tap_offset(tap);
        float d = scene_sdf(q);
        if (tap >= 0) {
            g[tap / 2] += sdf_tap_sign(tap) * d;
            tap += 1;
            if (tap == SDF_NORMAL_TAPS) {
                n = g * (1.0 / length(g));
                return true;
            }
        } else if (d < SDF_HIT_EPS) {
            p = q;
            tap = 0;
        } else {
            t = t + d * SDF_STEP_SCALE;
            if (t > t1 || i == SDF_MAX_STEPS - 1) {
                return false;
            }
        }
    }
    return false;
}

// What this pixel of a size-pixel view sees: its camera ray direction rd and the hit point p with
// its unit normal n; false on a miss, where rd alone is set.
bool sdf_pixel(vec2 size, out vec3 rd, out vec3 p, out vec3 n) {
    vec3 ro;
    camera_ray(gl_FragCoord.xy, size, ro, rd);
    float t;
    if (!sdf_hit(ro, rd, t, n)) {
        return false;
    }
    p = ro + rd * t;
    return true;
}

// Unit normal at p alone (the same taps), for callers that have a point but no ray.
vec3 sdf_normal(vec3 p) {
    vec3 g = vec3(0.0);
    for (int i = 0; i < SDF_NORMAL_TAPS; ++i) {
        g[i / 2] += sdf_tap_sign(i) * scene_sdf(p + sdf_tap_offset(i));
    }
    return g * (1.0 / length(g));
}
