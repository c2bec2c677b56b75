// material_channels.glsl in WGSL: a glTF material's channels at one surface point (linear base colour,
// unit tangent-space normal, roughness, occlusion, metallic).
struct MaterialChannels {
    base_color: vec3<f32>,
    normal: vec3<f32>,
    roughness: f32,
    occlusion: f32,
    metallic: f32,
}
