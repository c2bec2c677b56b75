// Sparse multi-scale voxels' tables, for OpenGL and Vulkan GLSL (sparse_voxels.wgsl, sparse_voxels.hlsl
// for the others; emit.py has the layouts, codegen/voxel_index.py the cell -> slot indexes). Every
// read is an exact texelFetch; the network's P_voxel_slot / P_voxel_sphere call these.
#include <lib/texture_rows>

// Vulkan GLSL reads the tables without a sampler (GL_EXT_samplerless_texture_functions).
#ifdef VULKAN
#define SV_TABLE texture2D
#define SV_INDEX utexture2D
#define SV_GRID utexture3D
#else
#define SV_TABLE sampler2D
#define SV_INDEX usampler2D
#define SV_GRID usampler3D
#endif

// Item `index` of a float table laid out in rows of 2^log2w texels.
vec4 sv_row(SV_TABLE table, uint index, int log2w) {
    return texelFetch(table, rows_texel(index, log2w), 0);
}

// Whether `cell` lies in the 2^scale grid of a scale in scale_min..scale_max.
bool sv_in_grid(int scale, ivec3 cell, int scale_min, int scale_max) {
    return scale >= scale_min && scale <= scale_max
           && all(greaterThanEqual(cell, ivec3(0))) && all(lessThan(cell, ivec3(1 << scale)));
}

// slot + 1 of the voxel at `cell` of `scale` (0 = empty, outside the grid or the scale range) in the
// dense index: one R32UI 3D texture whose mip level L holds scale scale_max - L.
// (highp: ES 3.00 has no default precision for integer samplers.)
uint sv_slot_dense(highp SV_GRID grid, int scale, ivec3 cell, int scale_min, int scale_max) {
    if (!sv_in_grid(scale, cell, scale_min, scale_max)) return 0u;
    return texelFetch(grid, cell, scale_max - scale).r;
}

// The same in the bricks index: brick (cell >> log2b) of the scale at top_offset in `top` holds its
// row + 1 in `bricks` (0: no voxel in it), whose (2^log2b)^3 texels hold slot + 1 per cell.
uint sv_slot_bricks(highp SV_INDEX top, int top_log2w, highp SV_INDEX bricks, int bricks_log2w, int log2b,
                    uint top_offset, int scale, ivec3 cell, int scale_min, int scale_max) {
    if (!sv_in_grid(scale, cell, scale_min, scale_max)) return 0u;
    int m = max((1 << scale) >> log2b, 1);
    ivec3 c = cell >> log2b;
    uint row = texelFetch(top, rows_texel(top_offset + uint((c.z * m + c.y) * m + c.x), top_log2w), 0).r;
    if (row == 0u) return 0u;
    int b = 1 << log2b;
    ivec3 l = cell & (b - 1);
    uint u = ((row - 1u) << uint(3 * log2b)) + uint((l.z * b + l.y) * b + l.x);
    return texelFetch(bricks, rows_texel(u, bricks_log2w), 0).r;
}
