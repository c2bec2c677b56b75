// Texture-space PRT (the paper's baseline, Learnt Transfer, Dhawal et al. 2022 5.1): the 16 SH
// coefficients of cosine-weighted visibility baked into a uv-mapped texture (a 2D lookup array of
// 16 channels, four RGBA textures; techniques/prt/texture_prt.py bakes it). Shading is lib/prt.glsl's,
// unchanged: only where the transfer comes from differs from the learnt path.
// <prt_texture_network> (techniques/prt/texture_codegen.py) includes the lookup and defines
// PRT_TEXTURE_EVAL. Torch twin: techniques/prt/texture_prt.py texture_transfer.
#include <lib/prt>
#include <prt_texture_network>

// The baked transfer at texture coordinate uv (the mesh's, in the lookup-array texel convention).
void prt_texture_transfer(vec2 uv, out vec4 t[PRT_BLOCKS]) {
    vec4 x[PRT_TEXTURE_IN_BLOCKS];
    x[0] = vec4(uv, 0.0, 0.0);
    PRT_TEXTURE_EVAL(x, t);
}
