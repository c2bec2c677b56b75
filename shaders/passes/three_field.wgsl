fn inshade_field(ro: vec3<f32>, p: vec3<f32>/*net_textures*/) -> vec4<f32> {
    // A radiance field for a three.js node material (inshade export-three): three_field.glsl's steps
    // (lib/field_march), the radiance premultiplied by the coverage 1 - T; ro and p in the mesh's frame.
    let parts = field_march_parts(ro, normalize(p - ro)/*net_texture_names*/);
    return vec4<f32>(parts.rgb, 1.0 - parts.w);
}
