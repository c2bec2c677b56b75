fn inshade_material(uv: vec2<f32>/*net_textures*/) -> mat4x4<f32> {
    // A glTF material's channels at the mesh's TEXCOORD_0 (three's uv, v down; material_channels takes
    // inshade's mesh uv, v up) for a three.js node material (inshade export-three), packed for TSL:
    // columns (base colour, roughness), (normal, occlusion), (metallic).
    let c = material_channels(vec2<f32>(uv.x, 1.0 - uv.y)/*net_texture_names*/);
    return mat4x4<f32>(vec4<f32>(c.base_color, c.roughness), vec4<f32>(c.normal, c.occlusion),
                       vec4<f32>(c.metallic, 0.0, 0.0, 0.0), vec4<f32>(0.0));
}
