// The channel set a PBR shading reads (PbrSample), and its 8-lane packing as two vec4 in
// models/pbr_lanes.py LANES order:
//   a = (albedo.rgb [sRGB-encoded], normal.x), b = (normal.y, normal.z, roughness, ao)
// with the tangent-space normal stored as 0.5 + 0.5 n (x along +u, y along +v, z out). The lanes
// hold no metallic: it unpacks as 0. Torch twin, same operations in the same order:
// models/pbr_lanes.py unpack.
#include <lib/colour>

struct PbrSample {
    vec3 albedo;      // linear
    vec3 normal_ts;   // unit, tangent space (x along +u, y along +v, z out)
    float roughness;
    float metallic;
    float ao;
};

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
