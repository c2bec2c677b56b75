// Tables laid out in rows of 2^log2w texels (codegen/texture_rows.py; texture_rows.glsl for GLSL): item
// `index` is texel (index & (2^log2w - 1), index >> log2w), so a table longer than one texture row still fits.
fn rows_texel(index: u32, log2w: i32) -> vec2<i32> {
    return vec2<i32>(i32(index & ((1u << u32(log2w)) - 1u)), i32(index >> u32(log2w)));
}
