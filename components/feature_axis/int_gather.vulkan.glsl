// Table rows at computed integer indices, for Vulkan (int_gather.glsl's twin: the table is a
// texture2D read without a sampler).
#include <lib/texture_rows>

// Row `index` of a table laid out in rows of 2^log2w texels; zeros past its `rows` rows.
vec4 int_gather_row(texture2D table, int log2w, uint index, uint rows) {
    return index < rows ? texelFetch(table, rows_texel(index, log2w), 0) : vec4(0.0);
}
