// Mesh PRT pass on a glTF file (Learnt Transfer, Dhawal et al. 2022 4.1, deferred as passes/mesh_prt): the
// transfer network's PRT shading (lib/prt: diffuse, or + glossy) with the albedo the file's material
// gives the pixel -- its base colour, texture x factor, linear (lib/gltf_material's gltf_surface) --
// next to the file's reference shading (gltf_shade: the spec's BRDF under the same SH environment,
// with its normal map, metal, occlusion map and emission). They differ by design: PRT is diffuse
// (or Phong glossy) transfer with the shadows the mesh casts on itself; the reference has the spec's
// specular lobe, the normal map, the occlusion texture and the emission, and no cast shadows. The
// scene has no point lights: both are lit by the environment alone.
// u_prt_view (GLTF_VIEWS in techniques/prt/__init__.py; PRT_VIEW_* from <choices>): prt | reference |
// split (left half reference, right half PRT) | albedo (the base colour PRT multiplies, what the
// quality measurement shades its ground truth with). Debug u_prt_debug as passes/mesh_prt.frag.
// Torch reference of the prt view: techniques/prt/twin.py compose() with the albedo view's colours.
#include <lib/gltf_gbuffer>
#include <lib/prt_pass>
#include <choices>

uniform int u_prt_view;
layout(location = 0) out vec4 frag_color;

void main() {
    GltfPixel g;
    GltfSurface s;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, s)) {
        frag_color = prt_background(-g.v);
        return;
    }
    vec3 p = g.p, n = g.n, rd = -g.v;
    bool reference = u_prt_view == PRT_VIEW_REFERENCE
                     || (u_prt_view == PRT_VIEW_SPLIT && gl_FragCoord.x < 0.5 * u_size.x);
    if (reference && u_prt_debug == 0) {
        frag_color = vec4(gltf_shade(s, p, -rd, u_sh, 0), 1.0);
        return;
    }
    if (u_prt_view == PRT_VIEW_ALBEDO && u_prt_debug == 0) {
        frag_color = vec4(s.s.base_color, 1.0);
        return;
    }
    frag_color = prt_network_pixel(s.s.base_color, p, n, rd);
}
