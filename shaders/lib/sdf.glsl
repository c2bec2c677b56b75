// SDF scenes: sphere tracing and normals (camera rays: lib/camera). The scene itself is the generated
// chunk <sdf_scene> (codegen/sdf.py: chunks=sdf_chunks(scene)): scene_sdf(p), scene_albedo(p) and
// the constants SDF_MAX_STEPS, SDF_STEP_SCALE, SDF_HIT_EPS, SDF_NORMAL_EPS, SDF_BOUND_CENTER,
// SDF_BOUND_RADIUS. Torch twins, step for step, in models/sdf.py (trace, normals).
// World frame: right-handed, y up; the camera looks down -z (scene/camera.py).
#include <sdf_scene>

#include <lib/camera>

// Sphere tracing inside the bound sphere: step d * SDF_STEP_SCALE (< 1: smooth booleans and
// repetition give a bound, not an exact distance), hit when d < SDF_HIT_EPS, give up past the
// sphere's exit or after SDF_MAX_STEPS. Returns hit; t is the ray parameter of the last point.
// A ray grazing an edge or meeting a surface at a shallow angle crawls (steps shrink by about
// SDF_STEP_SCALE * sin(angle)) and may need ~180 steps; one that runs out is a miss, i.e. a
// sky-coloured hole in the surface: SDF_MAX_STEPS must cover them (geometry/sdf.py, default 256).
bool sdf_trace(vec3 ro, vec3 rd, out float t) {
    vec3 oc = ro - SDF_BOUND_CENTER;
    float b = oc.x * rd.x + oc.y * rd.y + oc.z * rd.z;
    float c = oc.x * oc.x + oc.y * oc.y + oc.z * oc.z - SDF_BOUND_RADIUS * SDF_BOUND_RADIUS;
    float h = b * b - c;
    float sq = sqrt(max(h, 0.0));
    t = max(-b - sq, 0.0);
    float t1 = -b + sq;
    if (h < 0.0 || t1 < 0.0) {
        return false;
    }
    for (int i = 0; i < SDF_MAX_STEPS; ++i) {
        float d = scene_sdf(ro + rd * t);
        if (d < SDF_HIT_EPS) {
            return true;
        }
        t = t + d * SDF_STEP_SCALE;
        if (t > t1) {
            return false;
        }
    }
    return false;
}

// Unit normal from the SDF gradient by central differences (step SDF_NORMAL_EPS). One call site
// in a loop: a compiler inlines every call of scene_sdf, and a big network inlined six times takes
// minutes to compile; the arithmetic (f(p + e) - f(p - e) per axis) is the same.
vec3 sdf_normal(vec3 p) {
    vec3 g = vec3(0.0);
    for (int i = 0; i < 6; ++i) {
        int axis = i / 2;
        float sgn = (i % 2 == 0) ? 1.0 : -1.0;
        vec3 e = vec3(0.0);
        e[axis] = sgn * SDF_NORMAL_EPS;
        g[axis] += sgn * scene_sdf(p + e);
    }
    return g * (1.0 / length(g));
}
