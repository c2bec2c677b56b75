// Tables laid out in rows of 2^log2w texels (codegen/texture_rows.py): item `index` is texel
// (index & (2^log2w - 1), index >> log2w), so a table longer than GL_MAX_TEXTURE_SIZE still fits.
ivec2 rows_texel(uint index, int log2w) {
    return ivec2(int(index & ((1u << uint(log2w)) - 1u)), int(index >> uint(log2w)));
}
