// pbr_set_gltf_channels.glsl in WGSL: the DI lanes at a mesh uv as a glTF material's channels (the
// network net_eval and the PBR_GLTF_* constants of <pbr_set_gltf_domain> placed before this chunk).
#include <lib/colour>
#include <lib/material_channels>

fn pbr_set_gltf_uv(uv: vec2<f32>) -> vec2<f32> {
    let x = (uv - PBR_GLTF_UV_ORIGIN) / PBR_GLTF_UV_EXTENT;
    return vec2<f32>(select(clamp(x.x, 0.0, 1.0), fract(x.x), PBR_GLTF_REPEAT_U),
                     select(clamp(x.y, 0.0, 1.0), fract(x.y), PBR_GLTF_REPEAT_V));
}

fn material_channels(uv: vec2<f32>/*net_textures*/) -> MaterialChannels {
    var x: array<vec4<f32>, NET_IN_BLOCKS>;
    x[0] = vec4<f32>(pbr_set_gltf_uv(uv), 0.0, 0.0);
    let y = net_eval(x/*net_texture_names*/);
    let a = y[0];
    let b = y[1];
    let nxy = vec2<f32>(a.w, b.x) * 2.0 - 1.0;
    var c: MaterialChannels;
    c.base_color = srgb_eotf(clamp(a.xyz, vec3<f32>(0.0), vec3<f32>(1.0)));
    c.normal = normalize(vec3<f32>(nxy, sqrt(max(1.0 - nxy.x * nxy.x - nxy.y * nxy.y, 0.0))));
    c.roughness = clamp(b.y, 0.0, 1.0);
    c.occlusion = clamp(b.z, 0.0, 1.0);
    c.metallic = clamp(b.w, 0.0, 1.0);
    return c;
}
