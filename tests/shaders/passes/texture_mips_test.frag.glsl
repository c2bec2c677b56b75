// Test pass for runtime/network.py mip-chained textures (tests/runtime/test_texture_mips.py): pixel (x, y)
// -> attachment 0: texelFetch(u_tex, (x, y), u_level) (a target the size of level u_level reads
// that level back texel for texel); attachment 1: textureLod(u_tex, uv, u_level) at the uv stored
// in texel (x, y) of u_inputs (hardware filtering within one level, as the texture's filter says).
#include <lib/test_pass>

uniform sampler2D u_tex;
uniform int u_level;
layout(location = 0) out vec4 out_fetch;
layout(location = 1) out vec4 out_lod;

void main() {
    out_fetch = texelFetch(u_tex, ivec2(gl_FragCoord.xy), u_level);
    out_lod = textureLod(u_tex, test_input(0).xy, float(u_level));
}
