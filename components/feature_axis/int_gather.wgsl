// Table rows at computed integer indices, in WGSL (int_gather.glsl for OpenGL; emit.py; torch twin
// torch_twin.py).
#include <lib/texture_rows>

// Row `index` of a table laid out in rows of 2^log2w texels; zeros past its `rows` rows.
fn int_gather_row(table: texture_2d<f32>, log2w: i32, index: u32, rows: u32) -> vec4<f32> {
    if (index >= rows) { return vec4<f32>(0.0); }
    return textureLoad(table, rows_texel(index, log2w), 0);
}
