fn inshade_sdf(ro: vec3<f32>, p: vec3<f32>/*net_textures*/) -> vec4<f32> {
    // An SDF for a three.js node material (inshade export-three): three_sdf.glsl's steps (lib/sdf's
    // trace, then albedo * E(n) / pi under the SH environment SH_ENVIRONMENT); a miss is alpha 0, which
    // the material's alpha test discards. ro and p in the mesh's frame.
    let rd = normalize(p - ro);
    var t: f32;
    var n: vec3<f32>;
    if (!sdf_hit(ro, rd, &t, &n/*net_texture_names*/)) {
        return vec4<f32>(0.0);
    }
    let q = ro + rd * t;
    return vec4<f32>(scene_albedo(q) * sh_irradiance(n, SH_ENVIRONMENT) * 0.318309873, 1.0);
}
