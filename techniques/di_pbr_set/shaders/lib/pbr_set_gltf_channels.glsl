// A glTF material's PBR set (Differentiable Indirection, Datta et al. 2023 4.2.1) decoded from the
// network at a mesh uv (TEXCOORD_0): material_channels(uv). Eight lanes, in
// techniques/di_pbr_set/gltf_lanes.py LANES order, as two vec4:
//   a = (albedo.rgb [sRGB-encoded], normal.x), b = (normal.y, roughness, occlusion, metallic)
// with the tangent-space normal's x, y stored as 0.5 + 0.5 n and z rebuilt as sqrt(1 - x^2 - y^2)
// (then normalised: lanes past the unit circle give a normal in the surface's plane).
// The lanes cover a rectangle of the mesh's uv (the generated <pbr_set_gltf_domain>:
// PBR_GLTF_MATERIAL, PBR_GLTF_UV_ORIGIN, PBR_GLTF_UV_EXTENT, PBR_GLTF_REPEAT_U/V).
// WGSL twin: pbr_set_gltf_channels.wgsl (three.js's WebGPURenderer).
#include <network>
#include <lib/colour>
#include <lib/material_channels>
#include <pbr_set_gltf_domain>

// Mesh uv -> the network's uv: the domain's rectangle mapped onto [0, 1]^2, wrapped along an axis
// whose textures repeat with the rectangle's period, clamped along one it spans.
vec2 pbr_set_gltf_uv(vec2 uv) {
    vec2 x = (uv - PBR_GLTF_UV_ORIGIN) / PBR_GLTF_UV_EXTENT;
    return vec2(PBR_GLTF_REPEAT_U ? fract(x.x) : clamp(x.x, 0.0, 1.0),
                PBR_GLTF_REPEAT_V ? fract(x.y) : clamp(x.y, 0.0, 1.0));
}

MaterialChannels material_channels(vec2 uv) {
    vec4 x[NET_IN_BLOCKS];
    x[0] = vec4(pbr_set_gltf_uv(uv), 0.0, 0.0);
    vec4 y[NET_OUT_BLOCKS];
    net_eval(x, y);
    vec4 a = y[0], b = y[1];
    vec2 nxy = vec2(a.w, b.x) * 2.0 - 1.0;
    MaterialChannels c;
    c.base_color = srgb_eotf(clamp(a.xyz, 0.0, 1.0));
    c.normal = normalize(vec3(nxy, sqrt(max(1.0 - nxy.x * nxy.x - nxy.y * nxy.y, 0.0))));
    c.roughness = clamp(b.y, 0.0, 1.0);
    c.occlusion = clamp(b.z, 0.0, 1.0);
    c.metallic = clamp(b.w, 0.0, 1.0);
    return c;
}
