// The mesh G-buffer a deferred pass reads (runtime/geometry.py MeshGBuffer, GBUFFER order; drawn by
// passes/mesh_gbuffer.frag into float targets the size of this pass's, so texel = pixel).
#include <lib/camera>

uniform sampler2D u_gbuffer_position;   // world position, w = 1 where the mesh covers the pixel
uniform sampler2D u_gbuffer_normal;     // unit interpolated normal
uniform sampler2D u_gbuffer_uv;         // texture coordinates
uniform sampler2D u_gbuffer_tangent;    // interpolated tangent, handedness in w

// The visible surface at this pixel: false in the background (no mesh there).
bool gbuffer_surface(ivec2 px, out vec3 position, out vec3 normal) {
    vec4 p = texelFetch(u_gbuffer_position, px, 0);
    position = p.xyz;
    normal = texelFetch(u_gbuffer_normal, px, 0).xyz;
    return p.w != 0.0;
}

// This pixel of a size-pixel view: its camera ray direction rd and the visible surface (p, n);
// false in the background, where rd alone is set.
bool gbuffer_pixel(vec2 size, out vec3 rd, out vec3 p, out vec3 n) {
    vec3 ro;
    camera_ray(gl_FragCoord.xy, size, ro, rd);
    return gbuffer_surface(ivec2(gl_FragCoord.xy), p, n);
}
