// End-to-end DI shading pipeline on the footprint plane (techniques/di_shading/train.py): the ground
// plane of lib/footprint seen at grazing angles, its PBR set read by a DI footprint sampler
// (<network_e2e>: trained through the frozen DI Disney decoder; <network_ind>: lambda = 0, the
// independently trained sampler) and shaded with the DI Disney decoder (lib/di_shading), or the
// appearance-filtered reference. SHADING_VIEW (VIEWS in techniques/di_shading/__init__.py, the
// SHADING_* names from <choices>):
//   0 end-to-end     e2e sampler at (fract uv, log2 footprint) + DI Disney
//   1 independent    ind sampler + DI Disney
//   2 reference      16 samples uv + a duv/dx + b duv/dy (a, b in {-3/8, -1/8, 1/8, 3/8}) of the
//                    uncompressed set (u_set0/1: RGBA8 + GL mips, REPEAT) at GL LOD
//                    log2 footprint - 2 + log2 N, each shaded with the analytic Disney BRDF, averaged
//   3 split          independent (left half) | end-to-end (right half)
//   4 trilinear      the uncompressed set at the pixel (GL trilinear at log2 footprint + log2 N, one
//                    sample) + DI Disney: the mip-mapped texture the samplers replace, same decoder
//   5 analytic       the same single trilinear sample + the analytic Disney BRDF
// Output: linear RGB x u_exposure, alpha 1 on the plane; locations 1-3 carry what the torch twin
// needs: (fract uv, log2 footprint, hit), (duv/dx, duv/dy), (world hit point, 1).
#include <network_e2e>
#include <network_ind>
#include <lib/camera>
#include <lib/footprint>
#include <lib/di_shading>
#include <choices>

#ifndef SHADING_VIEW
#define SHADING_VIEW SHADING_SPLIT
#endif
#if E2E_IN_DIM != 3 || E2E_OUT_DIM != 8 || IND_IN_DIM != 3 || IND_OUT_DIM != 8
#error "passes/shading_plane.frag needs (uv, log2_footprint) -> 8-lane samplers (techniques/di_shading)"
#endif
#if BRDF_IN_DIM != 1 || BRDF_OUT_DIM != 14
#error "passes/shading_plane.frag needs the roughness -> 14-lane DI Disney decoder bundle"
#endif

uniform vec2 u_size;
uniform float u_tile;
uniform float u_extent;
uniform float u_exposure;
uniform float u_light_x;
uniform float u_light_y;
uniform float u_light_z;
uniform float u_light_intensity;
uniform float u_ambient;
#if SHADING_VIEW == SHADING_REFERENCE || SHADING_VIEW == SHADING_TRILINEAR || SHADING_VIEW == SHADING_ANALYTIC
uniform sampler2D u_set0;   // lanes 0-3
uniform sampler2D u_set1;   // lanes 4-7
#endif
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_inputs;
layout(location = 2) out vec4 frag_derivatives;
layout(location = 3) out vec4 frag_position;

// The set's sample from the independent sampler <network_ind> or the end-to-end one <network_e2e>
// (the same inputs and lanes, checked above).
PbrSample shading_sampler(bool independent, vec2 uv, float lf) {
    vec4 x[E2E_IN_BLOCKS];
    x[0] = vec4(uv, lf, 0.0);
    vec4 y[E2E_OUT_BLOCKS];
    if (independent) {
        ind_eval(x, y);
    } else {
        e2e_eval(x, y);
    }
    return pbr_set_unpack(y[0], y[1]);
}

void main() {
    FootprintPixel f = footprint_pixel(u_size, u_tile, u_extent);
    vec2 dx = f.dx, dy = f.dy, tile_uv = f.tile_uv;
    float lf = f.log2_fp;
    float t = f.ro.y / max(-f.rd.y, 1e-6);
    vec3 p = f.ro + f.rd * t;
    frag_inputs = vec4(tile_uv, lf, f.hit ? 1.0 : 0.0);
    frag_derivatives = vec4(dx, dy);
    frag_position = vec4(p, 1.0);
    if (!f.hit) {
        frag_color = vec4(0.0);
        return;
    }
    DiShadingGeometry g = di_shading_geometry(p, u_eye, vec3(u_light_x, u_light_y, u_light_z), u_light_intensity);
#if SHADING_VIEW == SHADING_REFERENCE
    float lod = lf - 2.0 + log2(float(textureSize(u_set0, 0).x));
    vec3 sum = vec3(0.0);
    for (int j = 0; j < 4; ++j) {
        for (int i = 0; i < 4; ++i) {
            vec2 q = tile_uv + (float(i) * 0.25 - 0.375) * dx + (float(j) * 0.25 - 0.375) * dy;
            PbrSample s = pbr_set_unpack(textureLod(u_set0, q, lod), textureLod(u_set1, q, lod));
            sum += di_shading_analytic(s, g, u_ambient);
        }
    }
    vec3 rgb = sum * 0.0625;
#elif SHADING_VIEW == SHADING_TRILINEAR || SHADING_VIEW == SHADING_ANALYTIC
    float lod = lf + log2(float(textureSize(u_set0, 0).x));
    PbrSample s = pbr_set_unpack(textureLod(u_set0, tile_uv, lod), textureLod(u_set1, tile_uv, lod));
#if SHADING_VIEW == SHADING_TRILINEAR
    vec3 rgb = di_shading_learned(s, g, u_ambient);
#else
    vec3 rgb = di_shading_analytic(s, g, u_ambient);
#endif
#elif SHADING_VIEW == SHADING_END_TO_END
    vec3 rgb = di_shading_learned(shading_sampler(false, tile_uv, lf), g, u_ambient);
#elif SHADING_VIEW == SHADING_INDEPENDENT
    vec3 rgb = di_shading_learned(shading_sampler(true, tile_uv, lf), g, u_ambient);
#else
    vec3 rgb = di_shading_learned(shading_sampler(gl_FragCoord.x < 0.5 * u_size.x, tile_uv, lf), g, u_ambient);
#endif
    frag_color = vec4(rgb * u_exposure, 1.0);
}
