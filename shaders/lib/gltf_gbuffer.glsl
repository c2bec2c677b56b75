// A glTF mesh's pixel in the deferred G-buffer (runtime/geometry.py: position, normal, uv with the
// face's material in z, tangent, uv footprint) and the file's material there (lib/gltf_material's
// reference surface): what every pass that draws a glTF mesh starts from.
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/gltf_material>

uniform sampler2D u_gbuffer_uv_grad;
#ifdef GBUFFER_UV1   // a texture reads TEXCOORD_1: its uv and footprint (runtime/geometry.py)
uniform sampler2D u_gbuffer_uv1;
uniform sampler2D u_gbuffer_uv1_dy;
#endif

struct GltfPixel {
    vec3 p;          // world position
    vec3 n;          // interpolated normal
    vec3 v;          // towards the camera (unit)
    vec4 uv;         // (uv, material, coverage)
    vec4 tangent;    // (tangent, handedness)
    int material;
};

// The pixel at window position frag of a size-pixel view, and the reference surface there; false
// where no mesh covers it (g.v is then still the reversed view ray, for the background).
bool gltf_pixel(vec2 frag, vec2 size, out GltfPixel g, out GltfSurface s) {
    ivec2 px = ivec2(frag);
    vec3 ro, rd;
    camera_ray(frag, size, ro, rd);
    g.v = -rd;
    if (!gbuffer_surface(px, g.p, g.n)) return false;
    g.uv = texelFetch(u_gbuffer_uv, px, 0);
    g.tangent = texelFetch(u_gbuffer_tangent, px, 0);
    g.material = int(g.uv.z + 0.5);
    MaterialUV uv = material_uv(g.uv.xy, texelFetch(u_gbuffer_uv_grad, px, 0));
#ifdef GBUFFER_UV1
    material_uv1(uv, texelFetch(u_gbuffer_uv1, px, 0), texelFetch(u_gbuffer_uv1_dy, px, 0));
#endif
    s = gltf_surface(g.material, uv, g.n, g.tangent, g.v);
    return true;
}
