// Material-ball grid: BALL_COLS x BALL_ROWS analytically ray-traced spheres (orthographic, looking
// down -z; no mesh) lit by u_light_count point lights, shaded with the analytic or the learned BRDF.
// techniques/di_brdf/material_balls.py is the torch twin (same operations, same order); techniques/di_brdf/train.py
// writes the assets (scene.json settings drive the defines below).
//
// BRDF_MODEL_GGX: GGX. Columns sweep alpha_h over [GGX_ALPHA_LO, GGX_ALPHA_HI]; the network is the
//   learned D, net_eval((alpha_h, n.h)) -> D, evaluated per light.
// BRDF_MODEL_DISNEY: Disney. The network is the di_disney bundle: input the ball's grid coordinate,
//   outputs (lanes below) the five decoder lookups of the latent textures, the latent textures'
//   extra lanes, and the artist-parameter textures the analytic path reads. Evaluated once per
//   pixel; unused lanes (the other path's textures) are dead code the compiler removes.
// BRDF_VIEW_ANALYTIC, _LEARNED, _SPLIT (side by side: left half analytic, right half learned),
//   _DIFFUSE (diffuse-only baseline, albedo n.l / pi: the shader's fixed cost, for benchmarks).
// BRDF_MODEL_* and BRDF_VIEW_*: the program's choices (MODELS, VIEWS in techniques/di_brdf/__init__.py),
// generated into <choices>.
#include <network>
#include <lib/brdf>
#include <lib/di_brdf>
#include <lib/lights>
#include <choices>

#ifndef BRDF_MODEL
#define BRDF_MODEL BRDF_MODEL_DISNEY
#endif
#ifndef BRDF_VIEW
#define BRDF_VIEW BRDF_VIEW_SPLIT
#endif
#ifndef BALL_COLS
#define BALL_COLS 8
#endif
#ifndef BALL_ROWS
#define BALL_ROWS 1
#endif
#define BALL_RADIUS2 0.81          // 0.9^2
#define BALL_INV_RADIUS 1.11111116 // 1 / 0.9
#define BALL_BACKGROUND 0.02
#define GGX_KD_TERM 0.0795774683   // GGX_KD * 0.5 / pi
#define GGX_KS 0.25
#define GGX_ALPHA_LO 0.1
#define GGX_ALPHA_HI 1.0
#if BRDF_VIEW == BRDF_VIEW_SPLIT
#define BALL_HALVES 2.0
#else
#define BALL_HALVES 1.0
#endif

uniform vec2 u_size;
uniform vec4 u_view;
uniform int u_light_count;
layout(location = 0) out vec4 frag_color;
// u_lights: the scene's point lights, position relative to the ball centre in cell units.

vec3 ball_local(vec3 w, vec3 t, vec3 b, vec3 n) {
    return vec3(w.x * t.x + w.y * t.y + w.z * t.z, w.x * b.x + w.y * b.y + w.z * b.z,
                w.x * n.x + w.y * n.y + w.z * n.z);
}

float net_lane(in vec4 y[NET_OUT_BLOCKS], int i) {
    return y[i / 4][i % 4];
}

void main() {
    vec2 uv = u_view.xy + (gl_FragCoord.xy / u_size) * u_view.zw;
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) {
        frag_color = vec4(0.0);
        return;
    }
    float gx = uv.x * BALL_HALVES;
    float side = floor(gx);
    gx = gx - side;
    float X = gx * float(BALL_COLS), Y = uv.y * float(BALL_ROWS);
    float colf = floor(X), rowf = floor(Y);
    float x = (X - colf) * 2.0 - 1.0;
    float y = (Y - rowf) * 2.0 - 1.0;
    colf = clamp(colf, 0.0, float(BALL_COLS - 1));
    rowf = clamp(rowf, 0.0, float(BALL_ROWS - 1));
    float rr = x * x + y * y;
    if (rr >= BALL_RADIUS2) {
        frag_color = vec4(vec3(BALL_BACKGROUND), 1.0);
        return;
    }
    float z = sqrt(max(BALL_RADIUS2 - rr, 0.0));
    vec3 P = vec3(x, y, z);
    vec3 n = vec3(x * BALL_INV_RADIUS, y * BALL_INV_RADIUS, z * BALL_INV_RADIUS);
    float tl = inversesqrt(max(n.z * n.z + n.x * n.x, 1e-30));
    vec3 t = vec3(n.z * tl, 0.0, -n.x * tl);
    vec3 b = vec3(n.y * t.z, n.z * t.x - n.x * t.z, -n.y * t.x);
    vec3 v = ball_local(vec3(0.0, 0.0, 1.0), t, b, n);
    bool learned = BRDF_VIEW == BRDF_VIEW_LEARNED || (BRDF_VIEW == BRDF_VIEW_SPLIT && side >= 1.0);

#if BRDF_MODEL == BRDF_MODEL_DISNEY
    vec4 xin[NET_IN_BLOCKS];
    xin[0] = vec4(colf / float(max(BALL_COLS - 1, 1)), rowf / float(max(BALL_ROWS - 1, 1)), 0.0, 0.0);
    vec4 yo[NET_OUT_BLOCKS];
    net_eval(xin, yo);
    DisneyMaterial m;
    m.base_color = vec3(net_lane(yo, 30), net_lane(yo, 31), net_lane(yo, 32));
    m.roughness = net_lane(yo, 33);
    m.metallic = net_lane(yo, 34); m.anisotropic = net_lane(yo, 35);
    m.subsurface = net_lane(yo, 36); m.specular = net_lane(yo, 37);
    m.specular_tint = net_lane(yo, 38); m.sheen = net_lane(yo, 39);
    m.sheen_tint = net_lane(yo, 40); m.clearcoat = net_lane(yo, 41);
    m.clearcoat_gloss = net_lane(yo, 42);
    DiDisney d;
    d.ggx = vec3(net_lane(yo, 0), net_lane(yo, 1), net_lane(yo, 2));
    d.smith = net_lane(yo, 3);
    d.diff = vec4(net_lane(yo, 4), net_lane(yo, 5), net_lane(yo, 6), net_lane(yo, 7));
    d.coef = vec4(net_lane(yo, 8), net_lane(yo, 9), net_lane(yo, 10), net_lane(yo, 11));
    d.gloss = vec2(net_lane(yo, 12), net_lane(yo, 13));
    d.sheen_tint = net_lane(yo, 16);
    d.k = vec3(net_lane(yo, 20), net_lane(yo, 21), net_lane(yo, 17));
    d.albedo = vec3(net_lane(yo, 24), net_lane(yo, 25), net_lane(yo, 27));
#endif

    vec3 acc = vec3(0.0);
    // A loop bound that is a uniform (not a constant 4 with a break): llvmpipe would unroll the
    // constant loop and run all four bodies under masks, hiding the per-light cost.
    int lights = scene_lights(u_light_count);
    for (int i = 0; i < lights; ++i) {
        vec3 dl = u_lights[i].xyz - P;
        float dist2 = dl.x * dl.x + dl.y * dl.y + dl.z * dl.z;
        vec3 l = ball_local(dl * inversesqrt(dist2), t, b, n);
        vec3 f;
#if BRDF_MODEL == BRDF_MODEL_GGX
        float a = GGX_ALPHA_LO + (GGX_ALPHA_HI - GGX_ALPHA_LO) * (colf / float(max(BALL_COLS - 1, 1)));
        vec3 h = brdf_half_vector(l, v);
        float dd;
        if (BRDF_VIEW == BRDF_VIEW_DIFFUSE) {
            dd = 0.0;  // diffuse-only baseline
        } else if (learned) {
            vec4 xg[NET_IN_BLOCKS];
            xg[0] = vec4(a, h.z, 0.0, 0.0);
            vec4 yg[NET_OUT_BLOCKS];
            net_eval(xg, yg);
            dd = yg[0].x;
        } else {
            dd = ggx(h.z, a);
        }
        float fs = l.z * (GGX_KD_TERM + GGX_KS * dd);
        f = vec3(l.z > 0.0 && v.z > 0.0 ? fs : 0.0);
#elif BRDF_VIEW == BRDF_VIEW_DIFFUSE
        f = m.base_color * (max(l.z, 0.0) * BRDF_INV_PI);
#else
        f = learned ? di_disney_brdf(d, l, v) : disney_brdf(m, l, v);
#endif
        acc += f * (u_lights[i].w / dist2);
    }
    frag_color = vec4(acc, 1.0);
}
