// A glTF material decoded by a network, for three.js's MeshStandardMaterial / MeshPhysicalMaterial
// (inshade export-three): declarations placed before three's main. inshade-three.js calls
// three_material_channels(vUv) where three reads its maps (map_fragment) and hands the channels to
// three's own shading: base colour, roughness, metalness, the normal map's tangent-space normal,
// occlusion. <material_decoder> includes the technique's chunk that defines material_channels.
#include <material_decoder>

// three's uv is the file's TEXCOORD_0 (v down); material_channels takes inshade's mesh uv (v up)
MaterialChannels three_material_channels(vec2 gltf_uv) {
    return material_channels(vec2(gltf_uv.x, 1.0 - gltf_uv.y));
}
