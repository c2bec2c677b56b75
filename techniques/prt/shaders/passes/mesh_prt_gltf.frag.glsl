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
#include <lib/prt>
#include <choices>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_shading;          // PRT_DIFFUSE | PRT_GLOSSY
uniform float u_phong_exponent;
uniform float u_albedo;         // tint of the file's base colour
uniform float u_kd;
uniform float u_ks;
uniform int u_prt_debug;
uniform int u_prt_view;
layout(location = 0) out vec4 frag_color;

void main() {
    GltfPixel g;
    GltfSurface s;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, s)) {
        frag_color = u_prt_debug > 0 ? vec4(0.0) : vec4(sh_background(-g.v, u_sh), 1.0);
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
    vec4 tr[PRT_BLOCKS];
    prt_transfer(p, n, tr);
    if (u_prt_debug > 0) {
        frag_color = prt_debug(u_prt_debug, tr, p, n);
        return;
    }
    vec3 albedo = s.s.base_color * u_albedo;
    frag_color = vec4(prt_shade(tr, albedo, n, rd, u_sh, u_shading, u_phong_exponent, u_kd, u_ks), 1.0);
}
