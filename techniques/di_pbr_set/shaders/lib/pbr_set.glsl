// A PBR texture set (Differentiable Indirection, Datta et al. 2023 4.2.1: "for PBR textures k includes albedo, normal, AO, roughness")
// shaded on a mesh. Eight lanes, in models/pbr_lanes.py LANES order, as two vec4:
//   a = (albedo.rgb [sRGB-encoded], normal.x), b = (normal.y, normal.z, roughness, ao)
// with the tangent-space normal stored as 0.5 + 0.5 n (x along +u, y along +v, z out). The
// compressed set (the DI bundle) and the uncompressed one (two RGBA8 textures of the same lanes)
// feed the same pbr_set_shade, so a side-by-side view differs by the compression alone.
// Shading: lib/pbr_shading with metallic 0 (the set has no metallic lane).
// Torch twin, same operations in the same order: models/pbr_lanes.py unpack, techniques/di_pbr_set/render.py shade.
#include <lib/colour>
#include <lib/pbr_shading>

PbrSample pbr_set_unpack(vec4 a, vec4 b) {
    PbrSample s;
    s.albedo = srgb_eotf(clamp(a.xyz, 0.0, 1.0));
    vec3 n = vec3(a.w, b.x, b.y) * 2.0 - 1.0;
    float len2 = n.x * n.x + n.y * n.y + n.z * n.z;
    s.normal_ts = len2 > 1e-12 ? n * inversesqrt(len2) : vec3(0.0, 0.0, 1.0);
    s.roughness = clamp(b.z, 0.0, 1.0);
    s.metallic = 0.0;
    s.ao = clamp(b.w, 0.0, 1.0);
    return s;
}
