// Sparse multi-scale voxels' tables in HLSL and Slang (sparse_voxels.glsl for GLSL; emit.py has the
// layouts, codegen/voxel_index.py the cell -> slot indexes). Every read is an exact Load; the
// network's P_voxel_slot / P_voxel_sphere call these.
#include <lib/texture_rows>

// Item `index` of a float table laid out in rows of 2^log2w texels.
float4 sv_row(Texture2D<float4> table, uint index, int log2w) {
    return table.Load(int3(rows_texel(index, log2w), 0));
}

// Whether `cell` lies in the 2^scale grid of a scale in scale_min..scale_max.
bool sv_in_grid(int scale, int3 cell, int scale_min, int scale_max) {
    if (scale < scale_min || scale > scale_max) return false;
    return all(cell >= (int3)0) && all(cell < (int3)(1 << scale));
}

// slot + 1 of the voxel at `cell` of `scale` (0 = empty, outside the grid or the scale range) in the
// dense index: one R32UI 3D texture whose mip level L holds scale scale_max - L.
uint sv_slot_dense(Texture3D<uint4> grid, int scale, int3 cell, int scale_min, int scale_max) {
    if (!sv_in_grid(scale, cell, scale_min, scale_max)) return 0u;
    return grid.Load(int4(cell, scale_max - scale)).r;
}

// The same in the bricks index: brick (cell >> log2b) of the scale at top_offset in `top` holds its
// row + 1 in `bricks` (0: no voxel in it), whose (2^log2b)^3 texels hold slot + 1 per cell.
uint sv_slot_bricks(Texture2D<uint4> top, int top_log2w, Texture2D<uint4> bricks, int bricks_log2w, int log2b,
                    uint top_offset, int scale, int3 cell, int scale_min, int scale_max) {
    if (!sv_in_grid(scale, cell, scale_min, scale_max)) return 0u;
    int m = max((1 << scale) >> log2b, 1);
    int3 c = cell >> log2b;
    uint row = top.Load(int3(rows_texel(top_offset + uint((c.z * m + c.y) * m + c.x), top_log2w), 0)).r;
    if (row == 0u) return 0u;
    int b = 1 << log2b;
    int3 l = cell & (b - 1);
    uint u = ((row - 1u) << uint(3 * log2b)) + uint((l.z * b + l.y) * b + l.x);
    return bricks.Load(int3(rows_texel(u, bricks_log2w), 0)).r;
}
