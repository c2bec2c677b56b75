// A glTF metallic-roughness material's channels at one surface point, as a network decodes them for a
// host that shades them itself (inshade export-three hands them to three.js's own PBR): base colour
// in linear light, the tangent-space normal (unit; x along the tangent, y along the bitangent, z out,
// the convention of glTF's normal textures), roughness, occlusion and metallic in [0, 1].
struct MaterialChannels {
    vec3 base_color;
    vec3 normal;
    float roughness;
    float occlusion;
    float metallic;
};
