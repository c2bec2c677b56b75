// The layered reference material of neural_appearance; the torch twin is
// techniques/neural_appearance/reference.py (same operations in the same order), the channel
// layout and the decoding constants are documented in techniques/neural_appearance/material.py.
// p0 = (base rgb, roughness), p1 = (anisotropy, direction, slope x, slope y),
// p2 = (metallic, coat weight, coat roughness, mask), all texture values in [0, 1].
// light/view: unit vectors in the geometric frame (z = mesh normal, x = tangent, y = bitangent).
// Returns f * cos (the factor on incident radiance from `light`), RGB.
#include <lib/brdf>

#define NA_PI 3.14159265
#define NA_INV_PI 0.318309886
#define NA_ALPHA_MIN 0.03     // material.ALPHA_MIN
#define NA_COS_MIN 1e-6       // denominators: cosines never below this

uniform vec2 u_na_roughness_range;
uniform float u_na_anisotropy_max;
uniform float u_na_slope_scale;
uniform float u_na_coat_ior;
uniform vec2 u_na_coat_roughness_range;
uniform float u_na_smudge_coat_roughness;
uniform float u_na_dust_weight;
uniform vec3 u_na_dust_colour;

uniform sampler2D u_na_param0;
uniform sampler2D u_na_param1;
uniform sampler2D u_na_param2;

// Height-correlated Smith Lambda of anisotropic GGX (w.z > 0).
float na_lambda(vec3 w, float ax, float ay) {
    float x = w.x * ax;
    float y = w.y * ay;
    float z2 = max(w.z * w.z, NA_COS_MIN * NA_COS_MIN);
    return (sqrt(1.0 + (x * x + y * y) / z2) - 1.0) * 0.5;
}

// D(h) G2(l, v) / (4 v.z): the cosine-weighted microfacet term without Fresnel.
float na_ggx_dg(vec3 l, vec3 v, vec3 h, float ax, float ay) {
    float hx = h.x / ax;
    float hy = h.y / ay;
    float q = hx * hx + hy * hy + h.z * h.z;
    float d = 1.0 / (NA_PI * ax * ay * (q * q));
    float g = 1.0 / (1.0 + na_lambda(l, ax, ay) + na_lambda(v, ax, ay));
    return d * g / (4.0 * max(v.z, NA_COS_MIN));
}

float na_schlick(float f0, float c) {
    return f0 + (1.0 - f0) * brdf_pow5(1.0 - c);
}

vec3 na_reflectance(vec4 p0, vec4 p1, vec4 p2, vec3 light, vec3 view) {
    if (light.z <= 0.0 || view.z <= 0.0) return vec3(0.0);
    // base: decode
    vec3 base = p0.xyz;
    float r = u_na_roughness_range.x + (u_na_roughness_range.y - u_na_roughness_range.x) * p0.w;
    float alpha = max(r * r, NA_ALPHA_MIN);
    float aspect = sqrt(1.0 - u_na_anisotropy_max * p1.x);
    float ax = max(alpha / aspect, NA_ALPHA_MIN);
    float ay = max(alpha * aspect, NA_ALPHA_MIN);
    float phi = NA_PI * p1.y;
    float c = cos(phi);
    float s = sin(phi);
    float sx = (2.0 * p1.z - 1.0) * u_na_slope_scale;
    float sy = (2.0 * p1.w - 1.0) * u_na_slope_scale;
    // shading frame: normal from the slopes, tangent = the brush direction projected off it
    float ni = inversesqrt(sx * sx + sy * sy + 1.0);
    vec3 n = vec3(-sx * ni, -sy * ni, ni);
    float nt = n.x * c + n.y * s;
    vec3 t = vec3(c - n.x * nt, s - n.y * nt, -(n.z * nt));
    t = t * inversesqrt(max(t.x * t.x + t.y * t.y + t.z * t.z, 1e-12));
    vec3 b = vec3(n.y * t.z - n.z * t.y, n.z * t.x - n.x * t.z, n.x * t.y - n.y * t.x);
    vec3 ls = vec3(light.x * t.x + light.y * t.y + light.z * t.z,
                   light.x * b.x + light.y * b.y + light.z * b.z,
                   light.x * n.x + light.y * n.y + light.z * n.z);
    vec3 vs = vec3(view.x * t.x + view.y * t.y + view.z * t.z,
                   view.x * b.x + view.y * b.y + view.z * b.z,
                   view.x * n.x + view.y * n.y + view.z * n.z);
    // base: Lambert + tinted anisotropic GGX conductor, mixed by metallic
    vec3 under = vec3(0.0);
    if (ls.z > 0.0 && vs.z > 0.0) {
        vec3 hs = brdf_half_vector(ls, vs);
        float hl = hs.x * ls.x + hs.y * ls.y + hs.z * ls.z;
        float f5 = brdf_pow5(1.0 - hl);
        vec3 fm = base + (1.0 - base) * f5;
        float spec = na_ggx_dg(ls, vs, hs, ax, ay);
        float m = p2.x;
        under = (1.0 - m) * base * (NA_INV_PI * ls.z) + m * fm * spec;
    }
    // clear coat on the geometric normal, roughened by the smudge mask
    float w = p2.y;
    float rc = min(u_na_coat_roughness_range.x + (u_na_coat_roughness_range.y - u_na_coat_roughness_range.x) * p2.z
                   + u_na_smudge_coat_roughness * p2.w, 1.0);
    float ac = max(rc * rc, NA_ALPHA_MIN);
    float e = (u_na_coat_ior - 1.0) / (u_na_coat_ior + 1.0);
    float f0c = e * e;
    vec3 h = brdf_half_vector(light, view);
    float hlc = h.x * light.x + h.y * light.y + h.z * light.z;
    float coat = w * na_schlick(f0c, hlc) * na_ggx_dg(light, view, h, ac, ac);
    // Fresnel-weighted layering: what enters and leaves the coat
    float att = (1.0 - w * na_schlick(f0c, light.z)) * (1.0 - w * na_schlick(f0c, view.z));
    vec3 layered = coat + att * under;
    // dust: a rough diffuse mixed in where the mask is
    float wd = u_na_dust_weight * p2.w;
    return (1.0 - wd) * layered + wd * u_na_dust_colour * (NA_INV_PI * light.z);
}

// The three parameter textures at uv, trilinear through their mips (lod as textureLod takes it).
void na_fetch_parameters(vec2 uv, float lod, out vec4 p0, out vec4 p1, out vec4 p2) {
    p0 = textureLod(u_na_param0, uv, lod);
    p1 = textureLod(u_na_param1, uv, lod);
    p2 = textureLod(u_na_param2, uv, lod);
}
