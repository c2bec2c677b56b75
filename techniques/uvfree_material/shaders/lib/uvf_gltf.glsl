// A glTF file's material channels as a UV-free decoder learnt them (techniques/uvfree_material,
// gltf_channels.py): the network <network_mat> (mesh_features -> MLP) at a visibility-buffer point,
// put into the reference surface of lib/gltf_material in place of the file's values. A channel the
// decoder does not output (UVG_LANE_* -1, from the generated <uvf_gltf_channels>) stays the file's.
// Stored values: base colour and emissive / UVG_EMISSIVE_SCALE sRGB-encoded, the tangent-space
// normal as n * 0.5 + 0.5, metallic, roughness and occlusion as they are.
#include <network_mat>
#include <uvf_gltf_channels>
#include <lib/gltf_material>

#if !defined(MAT_IN_UINT_DIM) || MAT_OUT_DIM != UVG_LANES
#error "passes/mesh_uvfree_gltf.frag needs a (triangle uint, barycentric) network with the bundle's render.channels lanes"
#endif
#include <lib/uvf_decoder>

float uvg_lane(in vec4 y[MAT_OUT_BLOCKS], int i) {
    return y[i / 4][i % 4];
}

vec3 uvg_lanes3(in vec4 y[MAT_OUT_BLOCKS], int i) {
    return vec3(uvg_lane(y, i), uvg_lane(y, i + 1), uvg_lane(y, i + 2));
}

// The decoded channels at face k, barycentrics t = (t0, t1), replacing those of `s`: the surface
// gltf_surface(m, ...) made at the same pixel, ng the interpolated normal, tangent the G-buffer's,
// v towards the camera (the normal is mapped in the frame gltf_surface used).
void uvg_decode(uint k, vec2 t, int m, vec3 ng, vec4 tangent, vec3 v, inout GltfSurface s) {
    vec4 y[MAT_OUT_BLOCKS];
    uvf_eval(k, t, y);
    s.s.base_color = srgb_eotf(clamp(uvg_lanes3(y, UVG_LANE_BASE_COLOR), 0.0, 1.0));
    s.s.metallic = clamp(uvg_lane(y, UVG_LANE_METALLIC), 0.0, 1.0);
    s.s.roughness = clamp(uvg_lane(y, UVG_LANE_ROUGHNESS), MATERIAL_MIN_ROUGHNESS, 1.0);
#if UVG_LANE_NORMAL >= 0
    vec3 nt = uvg_lanes3(y, UVG_LANE_NORMAL) * 2.0 - 1.0;
    float len2 = dot(nt, nt);
    nt = len2 > 1e-12 ? nt * inversesqrt(len2) : vec3(0.0, 0.0, 1.0);
    vec3 tt, bb;
    gltf_tangent_frame(ng, tangent, tt, bb);
    if (material_param(m, 5).x > 0.5 && gltf_dot(ng, v) < 0.0) {   // the back of a double-sided surface
        ng = -ng; tt = -tt; bb = -bb;
    }
    s.n = gltf_mapped_normal(nt, tt, bb, ng);
    vec3 at = s.at - s.n * gltf_dot(s.n, s.at);   // the file's anisotropy direction, about the new normal
    s.at = at * inversesqrt(max(gltf_dot(at, at), 1e-30));
    s.ab = cross(s.n, s.at);
#endif
#if UVG_LANE_OCCLUSION >= 0
    s.occlusion = clamp(uvg_lane(y, UVG_LANE_OCCLUSION), 0.0, 1.0);
#endif
#if UVG_LANE_EMISSIVE >= 0
    s.emissive = srgb_eotf(clamp(uvg_lanes3(y, UVG_LANE_EMISSIVE), 0.0, 1.0)) * UVG_EMISSIVE_SCALE;
#endif
}
