// Test pass for 3D textures with mip chains and 2D texture arrays (tests/runtime/test_texture_arrays.py).
// Defines: TEX_ARRAY (sampler2DArray), TEX_2D (sampler2D, fetch only), else sampler3D; TEX_UINT (the usampler kind, uvec4 output),
// TEX_SAMPLE (filtered lookups instead of fetches).
// Fetch mode: pixel (x, y) of a W x (H * D) target -> texelFetch(u_tex, (x, y % u_rows, y / u_rows),
// u_level), i.e. slice/layer z = y / u_rows, row y % u_rows (u_rows = H of level u_level), so a
// level [D, H, W, C] reads back as the target [D * H, W, 4] reshaped to [D, H, W, 4].
// Sample mode: pixel (x, y) -> textureLod(u_tex, the (u, v, layer or w) stored in texel (x, y) of
// u_coords, u_level).

#if defined(TEX_ARRAY) && defined(TEX_UINT)
uniform usampler2DArray u_tex;
#elif defined(TEX_ARRAY)
uniform sampler2DArray u_tex;
#elif defined(TEX_2D) && defined(TEX_UINT)
uniform usampler2D u_tex;
#elif defined(TEX_2D)
uniform sampler2D u_tex;
#elif defined(TEX_UINT)
uniform usampler3D u_tex;
#else
uniform sampler3D u_tex;
#endif

#ifdef TEX_UINT
layout(location = 0) out uvec4 out_value;
#else
layout(location = 0) out vec4 out_value;
#endif
uniform sampler2D u_coords;
uniform int u_level;
uniform int u_rows;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
#ifdef TEX_SAMPLE
    out_value = textureLod(u_tex, texelFetch(u_coords, px, 0).xyz, float(u_level));
#elif defined(TEX_2D)
    out_value = texelFetch(u_tex, px, u_level);
#else
    out_value = texelFetch(u_tex, ivec3(px.x, px.y % u_rows, px.y / u_rows), u_level);
#endif
}
