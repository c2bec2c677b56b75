// Table rows at computed integer indices, in HLSL and Slang (int_gather.glsl for OpenGL; emit.py;
// torch twin torch_twin.py).
#include <lib/texture_rows>

// Row `index` of a table laid out in rows of 2^log2w texels; zeros past its `rows` rows.
float4 int_gather_row(Texture2D<float4> table, int log2w, uint index, uint rows) {
    if (index >= rows) return (float4)0.0;
    return table.Load(int3(rows_texel(index, log2w), 0));
}
