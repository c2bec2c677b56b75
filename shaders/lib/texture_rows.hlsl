// Tables laid out in rows of 2^log2w texels (codegen/texture_rows.py; texture_rows.glsl for GLSL): item
// `index` is texel (index & (2^log2w - 1), index >> log2w), so a table longer than one texture row still fits.
int2 rows_texel(uint index, int log2w) {
    return int2(int(index & ((1u << uint(log2w)) - 1u)), int(index >> uint(log2w)));
}
