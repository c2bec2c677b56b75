// Test pass for runtime/network.py mip-chained textures (tests/runtime/test_texture_mips.py): pixel (x, y)
// -> attachment 0: texelFetch(u_tex, (x, y), u_level) (a target the size of level u_level reads
// that level back texel for texel); attachment 1: textureLod(u_tex, uv, u_level) at the uv stored
// in texel (x, y) of u_uvs (hardware filtering within one level, as the texture's filter says).

uniform sampler2D u_tex;
uniform sampler2D u_uvs;
uniform int u_level;
layout(location = 0) out vec4 out_fetch;
layout(location = 1) out vec4 out_lod;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_fetch = texelFetch(u_tex, px, u_level);
    out_lod = textureLod(u_tex, texelFetch(u_uvs, px, 0).xy, float(u_level));
}
