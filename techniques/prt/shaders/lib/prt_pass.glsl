// What every PRT pass (SDF, mesh, texture-space, glTF) does with a pixel once it has the transfer:
// the settings they share (view size, SH environment, shading mode, Phong exponent, albedo tint,
// kd, ks, debug view), a covered pixel's colour (a debug view, or lib/prt shading of the pixel's
// base colour) and an uncovered one's (the band-limited environment max(L(rd), 0); 0 in a debug view).
#include <lib/prt>

const vec3 PRT_MESH_ALBEDO = vec3(0.8);  // a mesh's base colour (techniques/prt/twin.py MESH_ALBEDO)

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_shading;          // PRT_DIFFUSE | PRT_GLOSSY
uniform float u_phong_exponent;
uniform float u_albedo;         // tint of the surface's base colour
uniform float u_kd;
uniform float u_ks;
uniform int u_prt_debug;

vec4 prt_background(vec3 rd) {
    return u_prt_debug > 0 ? vec4(0.0) : vec4(sh_background(rd, u_sh), 1.0);
}

// Transfer tr at p, unit normal n, base colour base_color, seen along the view ray rd.
vec4 prt_pixel(in vec4 tr[PRT_BLOCKS], vec3 base_color, vec3 p, vec3 n, vec3 rd) {
    if (u_prt_debug > 0) {
        return prt_debug(u_prt_debug, tr, p, n);
    }
    vec3 albedo = base_color * u_albedo;
    return vec4(prt_shade(tr, albedo, n, rd, u_sh, u_shading, u_phong_exponent, u_kd, u_ks), 1.0);
}

// The same with the transfer network's transfer at (p, n).
vec4 prt_network_pixel(vec3 base_color, vec3 p, vec3 n, vec3 rd) {
    vec4 tr[PRT_BLOCKS];
    prt_transfer(p, n, tr);
    return prt_pixel(tr, base_color, p, n, rd);
}
