// The prefiltered march of Deep Appearance Prefiltering (Bako et al. 2022): one beam per pixel
// through one scale of the sparse voxel grid, front to back, with the coverage-mask transmittance
// model. Torch twin (same steps, same float32 formulas): techniques/appearance_prefilter/march.py.
//
// Per pixel (ray ro, rd from lib/camera's camera_ray, ro already dollied: 0.5 + (ro - 0.5) * distance):
//  1. unit box [0,1]^3 entry t0 >= 0 and exit t1 (slab test); no hit: the environment only.
//  2. pixel width at distance d: d * px, px = 2 tan(fov_y / 2) / height = 2 / (u_proj[1][1] * height).
//     Footprint scale s_f = -log2(t0 * px); L = clamp(s_f + 1, S_MIN, S_MAX) (Nyquist: the next finer
//     scale); colour = mix(march(floor L), march(min(floor L + 1, S_MAX)), fract) (one march when
//     fract == 0). u_dap_force_scale >= 0 replaces L.
//  3. march(s): Amanatides-Woo DDA over the 2^s grid (at most 3 * 2^s + 3 cells) from the entry cell
//     floor((ro + rd t0) 2^s) (clamped into the grid); the next boundary of each axis is recomputed
//     from the integer cell every step ((cell + (step > 0)) / 2^s - ro) / rd, so no error accumulates;
//     ties go to x, then y. For each occupied cell (slot = DAP_voxel_slot != 0), sphere (c, r):
//     - w = -rd, (t, b) = dap_view_frame(w) (the same for every voxel of the pixel);
//     - beam width wb = dot(c - ro, rd) * px at the point q = ro + rd dot(c - ro, rd) closest to c;
//     - beam mask texel j = (u, v) of M x M lies at q + o_u wb t + o_v wb b, o = (idx + 0.5) / M - 0.5;
//       its voxel mask coordinates are x = (dot(q - c, t) + o_u wb) / r, y = (dot(q - c, b) + o_v wb) / r
//       (t, b unit and orthogonal: the same as ((p - c).t / r, (p - c).b / r)); the voxel's texel by
//       NEAREST, floor((x + 1) M / 2); outside [-1, 1): alpha 0;
//     - one decoder call dap_eval(slot - 1, [w, light_local]) -> coverage (M*M, row-major [v][u]),
//       albedo (3), phase (1), slice (B);
//     - weight_j = (1 - Lambda_j) alpha_j; wgt = mean_j weight_j; Lambda_j += weight_j;
//       radiance += wgt albedo (phase E_sun shadow + sum_b slice_b env(bin centre b in world));
//     - stop after the voxel when mean Lambda > 0.999.
//  4. rgb = radiance + (1 - mean Lambda) env(rd); alpha = mean Lambda; env = max(SH radiance, 0).
// shadow (when the caller turns shadows on) = dap_shadow: the shadow map (layer 0: the sun) at the
// sphere centre moved toward the sun by r + sqrt(3) / 2^S_MAX (out of the voxel's own caster cubes).
#define SHADOW_MAX_LAYERS 1
#include <lib/dap_frame>
#include <lib/lights>
#include <lib/spherical_harmonics>
#include <lib/shadow_map>
#include <lib/unit_box>

#if !defined(DAP_MASK) || !defined(DAP_BINS) || !defined(DAP_BINS_THETA) || !defined(DAP_BINS_PHI)
#error "lib/dap_march needs DAP_MASK, DAP_BINS, DAP_BINS_THETA, DAP_BINS_PHI (the record's <dap_config>)"
#endif
#if DAP_OUT_DIM != DAP_MASK * DAP_MASK + 4 + DAP_BINS || !defined(DAP_IN_UINT_DIM)
#error "lib/dap_march needs a (slot uint, view 3, light 3) -> (coverage M*M, albedo 3, phase 1, slice B) network 'dap'"
#endif

#define DAP_TEXELS (DAP_MASK * DAP_MASK)
#define DAP_ALBEDO DAP_TEXELS
#define DAP_PHASE (DAP_TEXELS + 3)
#define DAP_SLICE (DAP_TEXELS + 4)

// What a pixel's marches share: the beam's ray, frame, footprint and lighting.
struct DapPixel {
    vec3 ro;      // dollied eye
    vec3 rd;      // unit ray direction
    vec3 t;       // view frame of w = -rd
    vec3 b;
    vec3 light;   // sun direction in (t, b, w)
    vec3 sun;     // sun radiance E_sun
    vec3 sun_dir; // unit direction toward the sun (world)
    float px;     // pixel width per unit distance
    float t0;     // box entry (>= 0)
    vec3 env[DAP_BINS];   // environment radiance at the bin centres, in world
};

// One march's result: radiance (no background), mean coverage, coverage-weighted albedo.
struct DapResult {
    vec3 radiance;
    float coverage;
    vec3 albedo;
};


// The fractional scale L of the pixel's footprint at the box entry (step 2).
float dap_footprint_scale(float t0, float px, int force_scale) {
    if (force_scale >= 0) return clamp(float(force_scale), float(DAP_SCALE_MIN), float(DAP_SCALE_MAX));
    float s_f = -log2(max(t0 * px, 1e-30));
    return clamp(s_f + 1.0, float(DAP_SCALE_MIN), float(DAP_SCALE_MAX));
}

// Everything per pixel but the marches. E_sun and sun_dir: the scene's first directional light.
DapPixel dap_pixel(vec3 ro, vec3 rd, float px, float t0, vec3 sun_dir, vec3 sun_radiance,
                   in vec3 sh[SH_COEFFS]) {
    DapPixel p;
    p.ro = ro;
    p.rd = rd;
    p.px = px;
    p.t0 = t0;
    vec3 w = -rd;
    dap_view_frame(w, p.t, p.b);
    p.light = vec3(dot(sun_dir, p.t), dot(sun_dir, p.b), dot(sun_dir, w));
    p.sun = sun_radiance;
    p.sun_dir = sun_dir;
    for (int i = 0; i < DAP_BINS; ++i) {
        vec3 l = dap_bin_centre(i / DAP_BINS_PHI, i - (i / DAP_BINS_PHI) * DAP_BINS_PHI, DAP_BINS_THETA, DAP_BINS_PHI);
        p.env[i] = max(sh_radiance(l.x * p.t + l.y * p.b + l.z * w, sh), vec3(0.0));
    }
    return p;
}

float dap_lane(in vec4 y[DAP_OUT_BLOCKS], int i) {
    return y[i / 4][i - (i / 4) * 4];
}

#define DAP_SHADOW_BIAS 1e-4

// Global shadow of the voxel with `sphere` from the sun's shadow map (the record's ShadowRequest:
// the finest scale's occupied cells as cubes). The query point moves toward the sun past the
// voxel's own cubes (radius + one finest cell's diagonal): the voxel's own geometry already shadows
// it inside its phase (intra-voxel visibility), so only casters beyond it count. 1 without maps.
float dap_shadow(vec4 sphere, vec3 to_sun) {
    float h = 1.7320508 / float(1 << DAP_SCALE_MAX);
    return shadow_visibility(sphere.xyz + to_sun * (sphere.w + h), 0, DAP_SHADOW_BIAS);
}

// The voxel at `slot` (dap_voxel_slot's value, row + 1) seen by the pixel's beam: coverage update
// and radiance (step 3); `shadows`: the sun term times dap_shadow. The voxel mask texels of the
// beam's rows and columns come first: when no beam texel falls on the voxel's mask every alpha is
// 0 and the voxel adds nothing, so the decoder (the cost) is skipped (the twin need not skip).
void dap_shade_voxel(DapPixel p, uint slot, bool shadows, inout float lambda[DAP_TEXELS], inout DapResult res) {
    vec4 sphere = dap_voxel_sphere(slot - 1u);
    float d = dot(sphere.xyz - p.ro, p.rd);
    vec3 q = p.ro + p.rd * d;
    float wb = d * p.px;
    float qt = dot(q - sphere.xyz, p.t);
    float qb = dot(q - sphere.xyz, p.b);
    float inv_r = 1.0 / sphere.w;
    float half_m = 0.5 * float(DAP_MASK);
    int tu[DAP_MASK];
    int tv[DAP_MASK];
    bool any_u = false;
    bool any_v = false;
    for (int k = 0; k < DAP_MASK; ++k) {
        float o = (float(k) + 0.5) / float(DAP_MASK) - 0.5;
        tu[k] = int(floor(((qt + o * wb) * inv_r + 1.0) * half_m));
        tv[k] = int(floor(((qb + o * wb) * inv_r + 1.0) * half_m));
        any_u = any_u || (tu[k] >= 0 && tu[k] < DAP_MASK);
        any_v = any_v || (tv[k] >= 0 && tv[k] < DAP_MASK);
    }
    if (!any_u || !any_v) return;

    uvec4 xu[DAP_IN_UINT_BLOCKS];
    xu[0] = uvec4(slot - 1u, 0u, 0u, 0u);
    vec4 x[DAP_IN_BLOCKS];
    x[0] = vec4(-p.rd, p.light.x);
    x[1] = vec4(p.light.yz, 0.0, 0.0);
    vec4 y[DAP_OUT_BLOCKS];
    dap_eval(xu, x, y);

    // the mask lanes as a plain float array: a computed index into it is one scratch load, where a
    // computed lane of the vec4 array y becomes a select chain per use (minutes of llvmpipe JIT at 8x8)
    float mask[DAP_TEXELS];
    for (int k = 0; k < DAP_TEXELS; ++k) mask[k] = y[k / 4][k - (k / 4) * 4];
    float total = 0.0;
    for (int v = 0; v < DAP_MASK; ++v) {
        for (int u = 0; u < DAP_MASK; ++u) {
            bool inside = tu[u] >= 0 && tu[u] < DAP_MASK && tv[v] >= 0 && tv[v] < DAP_MASK;
            float alpha = inside ? mask[tv[v] * DAP_MASK + tu[u]] : 0.0;
            int j = v * DAP_MASK + u;
            float weight = (1.0 - lambda[j]) * alpha;
            lambda[j] += weight;
            total += weight;
        }
    }
    float wgt = total / float(DAP_TEXELS);
    vec3 albedo = vec3(dap_lane(y, DAP_ALBEDO), dap_lane(y, DAP_ALBEDO + 1), dap_lane(y, DAP_ALBEDO + 2));
    vec3 env = vec3(0.0);
    for (int i = 0; i < DAP_BINS; ++i) env += dap_lane(y, DAP_SLICE + i) * p.env[i];
    float shadow = shadows ? dap_shadow(sphere, p.sun_dir) : 1.0;
    res.radiance += wgt * albedo * (dap_lane(y, DAP_PHASE) * p.sun * shadow + env);
    res.albedo += wgt * albedo;
}

float dap_mean(in float lambda[DAP_TEXELS]) {
    float s = 0.0;
    for (int j = 0; j < DAP_TEXELS; ++j) s += lambda[j];
    return s / float(DAP_TEXELS);
}

// march(s) (step 3) over scale s of the grid; `shadows`: the sun term times dap_shadow.
DapResult dap_march(DapPixel p, int s, bool shadows) {
    DapResult res = DapResult(vec3(0.0), 0.0, vec3(0.0));
    float lambda[DAP_TEXELS];
    for (int j = 0; j < DAP_TEXELS; ++j) lambda[j] = 0.0;
    int n = 1 << s;
    float fn = float(n);
    vec3 d = vec3(abs(p.rd.x) < 1e-12 ? 1e-12 : p.rd.x, abs(p.rd.y) < 1e-12 ? 1e-12 : p.rd.y,
                  abs(p.rd.z) < 1e-12 ? 1e-12 : p.rd.z);
    vec3 inv = 1.0 / d;
    ivec3 step = ivec3(d.x > 0.0 ? 1 : -1, d.y > 0.0 ? 1 : -1, d.z > 0.0 ? 1 : -1);
    ivec3 ahead = ivec3(step.x > 0 ? 1 : 0, step.y > 0 ? 1 : 0, step.z > 0 ? 1 : 0);
    ivec3 cell = clamp(ivec3(floor((p.ro + p.rd * p.t0) * fn)), ivec3(0), ivec3(n - 1));
    float mean = 0.0;
    for (int i = 0; i < 3 * n + 3; ++i) {
        if (any(lessThan(cell, ivec3(0))) || any(greaterThanEqual(cell, ivec3(n)))) break;
        uint slot = dap_voxel_slot(s, cell);
        if (slot != 0u) {
            dap_shade_voxel(p, slot, shadows, lambda, res);
            mean = dap_mean(lambda);
            if (mean > 0.999) break;
        }
        vec3 tn = (vec3(cell + ahead) / fn - p.ro) * inv;
        if (tn.x <= tn.y && tn.x <= tn.z) {
            cell.x += step.x;
        } else if (tn.y <= tn.z) {
            cell.y += step.y;
        } else {
            cell.z += step.z;
        }
    }
    res.coverage = mean;
    return res;
}

// The scene's first directional light (the sun the voxels were baked under): its direction and
// radiance; none (zero radiance, straight up) when the scene has no directional light.
void dap_scene_sun(out vec3 dir, out vec3 radiance) {
    dir = vec3(0.0, 1.0, 0.0);
    radiance = vec3(0.0);
    for (int i = 0; i < INSHADE_MAX_LIGHTS; ++i) {
        if (i >= u_scene_light_count) break;
        if (u_light_kinds[i] == INSHADE_LIGHT_DIRECTIONAL) {
            dir = u_lights[i].xyz;
            radiance = vec3(u_lights[i].w);
            break;
        }
    }
}

// The pixel at fractional scale L: the marches of the two scales around it, blended linearly.
// They run in one loop with a trip count the compiler cannot unroll: the decoder is inlined into
// dap_march, and a second call site would double the program (llvmpipe compile time).
DapResult dap_march_at(DapPixel p, float L, bool shadows) {
    int lo = int(floor(L));
    float f = L - float(lo);
    DapResult a = DapResult(vec3(0.0), 0.0, vec3(0.0));
    int marches = f > 0.0 ? 2 : 1;
    for (int k = 0; k < marches; ++k) {
        DapResult m = dap_march(p, min(lo + k, DAP_SCALE_MAX), shadows);
        float weight = k == 0 ? (marches == 2 ? 1.0 - f : 1.0) : f;
        a.radiance += weight * m.radiance;
        a.coverage += weight * m.coverage;
        a.albedo += weight * m.albedo;
    }
    return a;
}
