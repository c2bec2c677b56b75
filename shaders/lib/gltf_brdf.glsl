// The glTF 2.0 metallic-roughness BRDF as the spec's appendix B defines it (the Khronos sample
// viewer's punctual-light shading), with the KHR lobes it layers: clearcoat (a GGX coat mixed in
// by its Fresnel), sheen (Charlie distribution and visibility, albedo scaling with the Enterprise
// PBR analytic fit of E), anisotropy (anisotropic GGX and height-correlated visibility), ior (F0).
// models/gltf_brdf.py is the numpy twin (same operations in the same order, float32).
// Vectors are world space and unit: n the shading normal, v towards the camera, l towards the light,
// at / ab the anisotropy direction and its bitangent (both orthogonal to n), nc the coat normal.

#define GLTF_PI 3.14159265
#define GLTF_INV_PI 0.318309886

struct GltfShading {
    vec3 base_color;       // linear
    float metallic;
    float roughness;       // perceptual; alpha = roughness^2
    float f0;              // dielectric F0 from the ior: ((ior - 1) / (ior + 1))^2
    float clearcoat;
    float clearcoat_roughness;
    vec3 sheen_color;
    float sheen_roughness;
    float anisotropy;      // strength in [0, 1]
};

float gltf_dot(vec3 a, vec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

float gltf_pow5(float x) {
    float x2 = x * x;
    return x2 * x2 * x;
}

float gltf_max3(vec3 c) {
    return max(max(c.x, c.y), c.z);
}

// GGX normal distribution (alpha = roughness^2)
float gltf_d_ggx(float nh, float alpha) {
    float a2 = alpha * alpha;
    float f = (nh * nh) * (a2 - 1.0) + 1.0;
    return a2 / (GLTF_PI * f * f);
}

// height-correlated Smith visibility, V = G / (4 |n.l| |n.v|)
float gltf_v_ggx(float nl, float nv, float alpha) {
    float a2 = alpha * alpha;
    float ggxv = nl * sqrt(nv * nv * (1.0 - a2) + a2);
    float ggxl = nv * sqrt(nl * nl * (1.0 - a2) + a2);
    float ggx = ggxv + ggxl;
    return ggx > 0.0 ? 0.5 / ggx : 0.0;
}

float gltf_d_ggx_anisotropic(float nh, float th, float bh, float at, float ab) {
    float a2 = at * ab;
    vec3 f = vec3(ab * th, at * bh, a2 * nh);
    float w2 = a2 / gltf_dot(f, f);
    return a2 * w2 * w2 * GLTF_INV_PI;
}

float gltf_v_ggx_anisotropic(float nl, float nv, float bv, float tv, float tl, float bl, float at, float ab) {
    float ggxv = nl * length(vec3(at * tv, ab * bv, nv));
    float ggxl = nv * length(vec3(at * tl, ab * bl, nl));
    return clamp(0.5 / (ggxv + ggxl), 0.0, 1.0);
}

float gltf_d_charlie(float nh, float r) {
    float inv_r = 1.0 / r;
    float sin2h = 1.0 - nh * nh;
    return (2.0 + inv_r) * pow(max(sin2h, 0.0), inv_r * 0.5) / (2.0 * GLTF_PI);
}

float gltf_sheen_l(float x, float r) {
    float s = (1.0 - r) * (1.0 - r);
    float a = mix(21.5473, 25.3245, s);
    float b = mix(3.82987, 3.32435, s);
    float c = mix(0.19823, 0.16801, s);
    float d = mix(-1.97760, -1.27393, s);
    float e = mix(-4.32054, -4.85967, s);
    return a / (1.0 + b * pow(x, c)) + d * x + e;
}

float gltf_sheen_lambda(float cos_theta, float r) {
    return abs(cos_theta) < 0.5 ? exp(gltf_sheen_l(cos_theta, r))
                                : exp(2.0 * gltf_sheen_l(0.5, r) - gltf_sheen_l(1.0 - cos_theta, r));
}

// n.v is kept off 0: at a silhouette (a normal map tilting n away from v) the lobe would be 0 * inf
float gltf_v_charlie(float nl, float nv, float r) {
    nv = max(nv, 1e-4);
    return 1.0 / ((1.0 + gltf_sheen_lambda(nv, r) + gltf_sheen_lambda(nl, r)) * (4.0 * nv * nl));
}

// directional albedo of the Charlie sheen lobe (the Enterprise PBR Shading Model's fit)
float gltf_sheen_e(float cos_theta, float r) {
    float c = 1.0 - cos_theta;
    return 0.65584461 * (c * c * c) + 1.0 / (4.16526551 + exp(-7.97291361 * sqrt(r) + 6.33516894));
}

// The sheen roughness used by the lobe: Charlie's D is singular at 0.
float gltf_sheen_r(float r) {
    return max(r, 0.07);
}

// f(v, l) * |n.l| for a unit light: what one punctual light of intensity 1 reflects.
vec3 gltf_brdf(GltfShading s, vec3 n, vec3 at_dir, vec3 ab_dir, vec3 nc, vec3 v, vec3 l) {
    float nl = clamp(gltf_dot(n, l), 0.0, 1.0);
    float nv = clamp(gltf_dot(n, v), 0.0, 1.0);
    if (nl <= 0.0) return vec3(0.0);   // a light below the surface adds nothing (every lobe has |n.l|)
    vec3 h = l + v;
    h = h * inversesqrt(max(gltf_dot(h, h), 1e-30));
    float nh = clamp(gltf_dot(n, h), 0.0, 1.0);
    float vh = clamp(gltf_dot(v, h), 0.0, 1.0);
    float alpha = s.roughness * s.roughness;
    float specular;
    if (s.anisotropy > 0.0) {
        float at = mix(alpha, 1.0, s.anisotropy * s.anisotropy);
        float ab = alpha;
        specular = gltf_v_ggx_anisotropic(nl, nv, gltf_dot(ab_dir, v), gltf_dot(at_dir, v), gltf_dot(at_dir, l),
                                          gltf_dot(ab_dir, l), at, ab)
                 * gltf_d_ggx_anisotropic(nh, gltf_dot(at_dir, h), gltf_dot(ab_dir, h), at, ab);
    } else {
        specular = gltf_v_ggx(nl, nv, alpha) * gltf_d_ggx(nh, alpha);
    }
    float schlick = gltf_pow5(1.0 - vh);
    vec3 diffuse = s.base_color * GLTF_INV_PI;
    float f_dielectric = s.f0 + (1.0 - s.f0) * schlick;
    vec3 f_metal = s.base_color + (1.0 - s.base_color) * schlick;
    vec3 dielectric = diffuse + (vec3(specular) - diffuse) * f_dielectric;    // mix(diffuse, spec, F)
    vec3 metal = f_metal * specular;
    vec3 colour = (dielectric + (metal - dielectric) * s.metallic) * nl;     // mix(dielectric, metal, metallic)
    if (gltf_max3(s.sheen_color) > 0.0) {
        float r = gltf_sheen_r(s.sheen_roughness);
        vec3 sheen = s.sheen_color * (gltf_d_charlie(nh, r) * gltf_v_charlie(nl, nv, r) * nl);
        float scale = min(1.0 - gltf_max3(s.sheen_color) * gltf_sheen_e(nv, r),
                          1.0 - gltf_max3(s.sheen_color) * gltf_sheen_e(nl, r));
        colour = sheen + colour * scale;
    }
    if (s.clearcoat > 0.0) {
        float cl = clamp(gltf_dot(nc, l), 0.0, 1.0);
        float cv = clamp(gltf_dot(nc, v), 0.0, 1.0);
        float ch = clamp(gltf_dot(nc, h), 0.0, 1.0);
        float ca = s.clearcoat_roughness * s.clearcoat_roughness;
        vec3 coat = vec3(gltf_v_ggx(cl, cv, ca) * gltf_d_ggx(ch, ca) * cl);
        float fc = s.clearcoat * (0.04 + 0.96 * gltf_pow5(1.0 - cv));
        colour = colour + (coat - colour) * fc;
    }
    return colour;
}

// Environment light of the glTF material from radiance SH: the diffuse part from the irradiance about
// n, the specular part as the split sum with the analytic environment BRDF of Karis (2014) and the SH
// radiance about the mirror direction standing in for the prefiltered map (exact for a white
// environment; a coarse, blurred stand-in for glossy reflections of a detailed one). occlusion scales
// both (the caller multiplies), as the sample viewer does.
vec3 gltf_env_brdf(vec3 f0, float roughness, float nv) {
    vec4 r = roughness * vec4(-1.0, -0.0275, -0.572, 0.022) + vec4(1.0, 0.0425, 1.04, -0.04);
    float a004 = min(r.x * r.x, exp2(-9.28 * nv)) * r.x + r.y;
    vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
    return f0 * ab.x + ab.y;
}

vec3 gltf_environment(GltfShading s, vec3 n, vec3 v, vec3 irradiance, vec3 radiance) {
    float nv = clamp(gltf_dot(n, v), 0.0, 1.0);
    vec3 f0 = vec3(s.f0) + (s.base_color - vec3(s.f0)) * s.metallic;
    vec3 spec = gltf_env_brdf(f0, s.roughness, nv);
    vec3 diffuse = s.base_color * (1.0 - s.metallic) * GLTF_INV_PI;
    vec3 colour = diffuse * irradiance * (vec3(1.0) - spec) + spec * radiance;
    if (s.clearcoat > 0.0) {
        float fc = s.clearcoat * (0.04 + 0.96 * gltf_pow5(1.0 - nv));
        colour = colour * (1.0 - fc) + radiance * fc;
    }
    return colour;
}
