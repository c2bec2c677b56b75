// Footprint-aware texturing of a ground plane (models/footprint_sampler.py has the torch side).
// World frame: right-handed, y up, the camera looks down -z (scene/camera.py fly/orbit cameras).
// The plane is y = 0; its texture coordinate is the hit's (x, -z) / tile, so one tile of the
// texture covers tile x tile world units, u to the right and v away from a camera at yaw 0.

#include <lib/camera>

// Tiled uv of the ray's hit with the plane y = 0, computed for every pixel (hit or not) so that
// dFdx/dFdy see defined neighbours: derivatives are undefined in non-uniform control flow.
// The plane is the square |x|, |z| <= extent. `hit` says whether the ray goes down from above
// the plane and lands on the square. A miss takes the uv below the eye instead of a point near
// the horizon: a quad (and a SIMD block: llvmpipe runs the texture filter on masked lanes too)
// that straddles the horizon then sees bounded derivatives, not footprints of 1e5 tiles, which
// make llvmpipe's anisotropic filter take minutes per frame.
vec2 footprint_plane_uv(vec3 ro, vec3 rd, float tile, float extent, out bool hit) {
    float t = ro.y / max(-rd.y, 1e-6);
    vec3 p = ro + rd * t;
    hit = ro.y > 0.0 && rd.y < 0.0 && max(abs(p.x), abs(p.z)) <= extent;
    p = hit ? p : ro;
    return vec2(p.x, -p.z) / tile;
}

// log2 of the pixel footprint in uv units, GL's isotropic LOD rule (GL 4.6 §8.14.1):
// rho = max(|duv/dx|, |duv/dy|), lambda = log2(rho * N) = this + log2(N) for an N x N texture.
// The paper takes |duv/dx x duv/dy|; the max axis is what GL's trilinear sampler (and the
// emulated one the network is trained against) uses. Clamped away from log2(0) = -inf.
float footprint_log2(vec2 dx, vec2 dy) {
    return 0.5 * log2(max(max(dot(dx, dx), dot(dy, dy)), 1e-30));
}

// What a full-screen pass over the plane knows of its pixel: the camera ray, the tiled uv of its
// hit (see footprint_plane_uv), the uv's screen derivatives, log2 of the footprint and the uv
// within its tile. Call it from main's uniform control flow (it takes derivatives).
struct FootprintPixel {
    vec3 ro;
    vec3 rd;
    vec2 uv;
    vec2 dx;
    vec2 dy;
    float log2_fp;
    vec2 tile_uv;
    bool hit;
};

FootprintPixel footprint_pixel(vec2 size, float tile, float extent) {
    FootprintPixel f;
    camera_ray(gl_FragCoord.xy, size, f.ro, f.rd);
    f.uv = footprint_plane_uv(f.ro, f.rd, tile, extent, f.hit);
    f.dx = dFdx(f.uv);
    f.dy = dFdy(f.uv);
    f.log2_fp = footprint_log2(f.dx, f.dy);
    f.tile_uv = fract(f.uv);
    return f;
}
