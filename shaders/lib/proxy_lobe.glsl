// The importance-sampling proxy of Real-Time Neural Appearance Models (Eqs. 8-11, App. A).
// Torch twin, with the derivation of every formula: models/proxy_lobe.py (same order of ops).
// Local frame, z = surface normal; `view` is known (towards the viewer), `light` is sampled.

#define PROXY_PI 3.14159265
#define PROXY_EPS 1e-12

// The 9 parameters [w_d, w_s, mu_d.xy, alpha_x, alpha_y, rho, mu_s.xy].
struct ProxyLobe {
    float w_d;
    float w_s;
    vec2 mu_d;
    vec2 alpha;
    float rho;
    vec2 mu_s;
};

// From the generated function's output blocks: lanes 0-3, 4-7 and lane 8.
ProxyLobe proxy_lobe(vec4 a, vec4 b, float c) {
    ProxyLobe p;
    p.w_d = a.x; p.w_s = a.y; p.mu_d = a.zw;
    p.alpha = b.xy; p.rho = b.z; p.mu_s = vec2(b.w, c);
    return p;
}

// Appendix A's quadratic tanh / sinh approximations (the proxy_params activation).
float proxy_tanh_q(float x) { return abs(x) < 2.0 ? x * (1.0 - 0.25 * abs(x)) : sign(x); }
float proxy_sinh_q(float x) { return x * (1.0 + 0.25 * abs(x)); }
float proxy_softmax2(float own, float other) { return 1.0 / (1.0 + exp(other - own)); }

vec3 proxy_normalize(vec3 x) { return x * inversesqrt(max(dot(x, x), PROXY_EPS)); }

vec3 proxy_diffuse_normal(ProxyLobe p) { return proxy_normalize(vec3(-p.mu_d, 1.0)); }

vec3 proxy_cosine(float u1, float u2) {
    float r = sqrt(u1);
    float phi = (2.0 * PROXY_PI) * u2;
    return vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
}

// M v with M of Eq. 11.
vec3 proxy_m(ProxyLobe p, vec3 v) {
    float s = sqrt(max(1.0 - p.rho * p.rho, 0.0));
    return vec3(p.alpha.x * v.x - p.mu_s.x * v.z,
                p.alpha.y * p.rho * v.x + p.alpha.y * s * v.y - p.mu_s.y * v.z, v.z);
}

// M^-1 v; det(M^-1) in `det`.
vec3 proxy_m_inverse(ProxyLobe p, vec3 v, out float det) {
    float s = sqrt(max(1.0 - p.rho * p.rho, 0.0));
    float px = (v.x + p.mu_s.x * v.z) / p.alpha.x;
    float py = (v.y + p.mu_s.y * v.z) / p.alpha.y;
    det = 1.0 / (p.alpha.x * p.alpha.y * s);
    return vec3(px, (py - p.rho * px) / s, v.z);
}

// u in [0, 1)^3: u.x < w_d picks the diffuse lobe; u.yz draws the direction.
vec3 proxy_sample(ProxyLobe p, vec3 view, vec3 u) {
    vec3 local = proxy_cosine(u.y, u.z);
    if (u.x < p.w_d) {
        // Duff et al. 2017 basis around n (n.z > 0 always)
        vec3 n = proxy_diffuse_normal(p);
        float a = -1.0 / (1.0 + n.z);
        float c = n.x * n.y * a;
        vec3 b1 = vec3(1.0 + n.x * n.x * a, c, -n.x);
        vec3 b2 = vec3(c, 1.0 + n.y * n.y * a, -n.y);
        return b1 * local.x + b2 * local.y + n * local.z;
    }
    vec3 h = proxy_normalize(proxy_m(p, local));
    return 2.0 * dot(view, h) * h - view;
}

// The density of proxy_sample's lights on the whole sphere (solid angle).
float proxy_pdf(ProxyLobe p, vec3 view, vec3 light) {
    float p_d = max(dot(light, proxy_diffuse_normal(p)), 0.0) / PROXY_PI;
    vec3 h = proxy_normalize(view + light);
    h = h.z < 0.0 ? -h : h;   // the generating half vector has z > 0
    float det;
    vec3 hp = proxy_m_inverse(p, h, det);
    float len2 = dot(hp, hp);
    float q = max(hp.z, 0.0) * inversesqrt(len2) / PROXY_PI;
    float p_s = q * det / (len2 * sqrt(len2)) / max(4.0 * abs(dot(light, h)), PROXY_EPS);
    return p.w_d * p_d + p.w_s * p_s;
}
