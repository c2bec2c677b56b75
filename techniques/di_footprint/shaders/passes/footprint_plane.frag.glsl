// Footprint-aware sampling on a tiled ground plane seen at grazing angles: full-screen ray-plane
// intersection (lib/footprint), uv from the hit, the pixel footprint from dFdx/dFdy of uv, and the
// texture read by one of FOOTPRINT_MODE (MODES in techniques/di_footprint/__init__.py, names from <choices>):
//   0 FOOTPRINT_DI           the generated DI network <network>: inputs (fract(uv), log2 footprint)
//   1 FOOTPRINT_TRILINEAR    GL trilinear: u_texture (RGB8 + mip chain, LINEAR_MIPMAP_LINEAR, REPEAT)
//   2 FOOTPRINT_ANISOTROPIC  GL anisotropic: u_texture_aniso (same texels, max anisotropy 16)
//   3 FOOTPRINT_BILINEAR     no mips: bilinear of the base level (aliases)
//   4 FOOTPRINT_EXPLICIT_LOD GL trilinear at our LOD, log2 footprint + log2 N (checks the emulation)
// The GL modes read sRGB-encoded RGB8 texels (filtered in encoded space, like the emulated sampler
// the network learns) and decode with srgb_eotf; the network decodes itself. Output: linear RGB,
// alpha = 1 on the plane, 0 off it (the display pass draws a background there).
// Location 1 gets the DI inputs (fract(uv), log2 footprint, hit) of the same pixel, so a parity test
// can feed torch exactly what the network saw (derivatives cannot be recomputed off-GPU).
// GL modes sample with textureGrad from the same derivatives: implicit-derivative texture() is
// undefined inside the hit branch (non-uniform control flow).
#include <lib/field_output>
#include <lib/footprint>
#include <lib/colour>
#include <choices>

#ifndef FOOTPRINT_MODE
#define FOOTPRINT_MODE FOOTPRINT_DI
#endif
#if NET_IN_DIM != 3
#error "passes/footprint_plane.frag needs a network with inputs uv (2) and log2_footprint (1)"
#endif

uniform vec2 u_size;   // target size in pixels
uniform float u_tile;    // world units per texture tile
uniform float u_extent;  // the plane is the square |x|, |z| <= u_extent world units
#if FOOTPRINT_MODE == FOOTPRINT_ANISOTROPIC
uniform sampler2D u_texture_aniso;
#elif FOOTPRINT_MODE != FOOTPRINT_DI
uniform sampler2D u_texture;
#endif
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_inputs;

vec3 footprint_network(vec2 uv, float log2_fp) {
    vec4 x[NET_IN_BLOCKS];
    x[0] = vec4(uv, log2_fp, 0.0);
    vec4 y[NET_OUT_BLOCKS];
    net_eval(x, y);
    return field_rgb(y);
}

void main() {
    FootprintPixel f = footprint_pixel(u_size, u_tile, u_extent);
    frag_inputs = vec4(f.tile_uv, f.log2_fp, f.hit ? 1.0 : 0.0);
    if (!f.hit) {
        frag_color = vec4(0.0);
        return;
    }
#if FOOTPRINT_MODE == FOOTPRINT_DI
    vec3 rgb = footprint_network(f.tile_uv, f.log2_fp);
#elif FOOTPRINT_MODE == FOOTPRINT_TRILINEAR
    vec3 rgb = srgb_eotf(textureGrad(u_texture, f.uv, f.dx, f.dy).rgb);
#elif FOOTPRINT_MODE == FOOTPRINT_ANISOTROPIC
    vec3 rgb = srgb_eotf(textureGrad(u_texture_aniso, f.uv, f.dx, f.dy).rgb);
#elif FOOTPRINT_MODE == FOOTPRINT_BILINEAR
    vec3 rgb = srgb_eotf(textureLod(u_texture, f.uv, 0.0).rgb);
#else
    float lod = f.log2_fp + log2(float(textureSize(u_texture, 0).x));
    vec3 rgb = srgb_eotf(textureLod(u_texture, f.uv, lod).rgb);
#endif
    frag_color = vec4(rgb, 1.0);
}
