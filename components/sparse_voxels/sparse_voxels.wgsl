// Sparse multi-scale voxels' tables in WGSL (sparse_voxels.glsl for GLSL; emit.py has the layouts,
// codegen/voxel_index.py the cell -> slot indexes). Every read is an exact textureLoad; the
// network's P_voxel_slot / P_voxel_sphere call these.
#include <lib/texture_rows>

// Item `index` of a float table laid out in rows of 2^log2w texels.
fn sv_row(table: texture_2d<f32>, index: u32, log2w: i32) -> vec4<f32> {
    return textureLoad(table, rows_texel(index, log2w), 0);
}

// Whether `cell` lies in the 2^scale grid of a scale in scale_min..scale_max.
fn sv_in_grid(scale: i32, cell: vec3<i32>, scale_min: i32, scale_max: i32) -> bool {
    return scale >= scale_min && scale <= scale_max
           && all(cell >= vec3<i32>(0)) && all(cell < vec3<i32>(1 << u32(scale)));
}

// slot + 1 of the voxel at `cell` of `scale` (0 = empty, outside the grid or the scale range) in the
// dense index: one R32UI 3D texture whose mip level L holds scale scale_max - L.
fn sv_slot_dense(grid: texture_3d<u32>, scale: i32, cell: vec3<i32>, scale_min: i32, scale_max: i32) -> u32 {
    if (!sv_in_grid(scale, cell, scale_min, scale_max)) {
        return 0u;
    }
    return textureLoad(grid, cell, scale_max - scale).r;
}

// The same in the bricks index: brick (cell >> log2b) of the scale at top_offset in `top` holds its
// row + 1 in `bricks` (0: no voxel in it), whose (2^log2b)^3 texels hold slot + 1 per cell.
fn sv_slot_bricks(top: texture_2d<u32>, top_log2w: i32, bricks: texture_2d<u32>, bricks_log2w: i32, log2b: i32,
                  top_offset: u32, scale: i32, cell: vec3<i32>, scale_min: i32, scale_max: i32) -> u32 {
    if (!sv_in_grid(scale, cell, scale_min, scale_max)) {
        return 0u;
    }
    let m = max((1 << u32(scale)) >> u32(log2b), 1);
    let c = cell >> vec3<u32>(u32(log2b));
    let row = textureLoad(top, rows_texel(top_offset + u32((c.z * m + c.y) * m + c.x), top_log2w), 0).r;
    if (row == 0u) {
        return 0u;
    }
    let b = 1 << u32(log2b);
    let l = cell & vec3<i32>(b - 1);
    let u = ((row - 1u) << u32(3 * log2b)) + u32((l.z * b + l.y) * b + l.x);
    return textureLoad(bricks, rows_texel(u, bricks_log2w), 0).r;
}
