// Environment lighting as an importance-sampled equirectangular texture. Numpy twin and the
// conventions (direction <-> texel, data layout, pdf): runtime/environment.py, EnvironmentSampler;
// the runtime binds the textures (EnvironmentTextures) when a program uses u_env_radiance.
//   u_env_radiance     RGBA32F [H, W]: rgb radiance, a = the texel's probability (float32, from the CDFs)
//   u_env_marginal     R32F [H+1, 1]: CDF over rows
//   u_env_conditional  R32F [W+1, H]: CDF over the columns of each row
// Directions are unit vectors, right-handed, y up; texel row 0 looks up (+y), u = 0.5 looks down -z.
uniform sampler2D u_env_radiance;
uniform sampler2D u_env_marginal;
uniform sampler2D u_env_conditional;
uniform ivec2 u_env_size;   // (W, H)

#define ENV_PI 3.14159265
#define ENV_SEARCH_STEPS 17  // ceil(log2(n)) steps for CDFs of up to 2^17 entries

// Nearest texel (column, row) of a direction, and sin(theta). theta from atan (not acos): accurate
// at the poles.
ivec2 env_texel(vec3 dir, out float sin_theta) {
    vec3 d = normalize(dir);
    sin_theta = length(d.xz);
    float theta = atan(sin_theta, d.y);
    float phi = atan(d.x, -d.z);
    int j = clamp(int(floor((phi * (0.5 / ENV_PI) + 0.5) * float(u_env_size.x))), 0, u_env_size.x - 1);
    int i = clamp(int(floor(theta * (1.0 / ENV_PI) * float(u_env_size.y))), 0, u_env_size.y - 1);
    return ivec2(j, i);
}

vec3 env_radiance(vec3 dir) {
    float s;
    return texelFetch(u_env_radiance, env_texel(dir, s), 0).rgb;
}

// Texel probability -> solid-angle density: uniform in (u, v) inside a texel, dw = 2 pi^2 sin(theta) du dv.
float env_density(float p, float sin_theta) {
    return sin_theta > 0.0 ? p * float(u_env_size.x * u_env_size.y) / (2.0 * ENV_PI * ENV_PI * sin_theta) : 0.0;
}

// Solid-angle pdf of env_sample at dir.
float env_pdf(vec3 dir) {
    float s;
    ivec2 t = env_texel(dir, s);
    return env_density(texelFetch(u_env_radiance, t, 0).a, s);
}

// The largest i in [0, n-1] with cdf[i] <= u (row `row` of `cdf`); a bounded binary search.
int env_search(sampler2D cdf, int row, int n, float u) {
    int lo = 0;
    int hi = n - 1;
    for (int k = 0; k < ENV_SEARCH_STEPS; ++k) {
        if (lo >= hi) break;
        int mid = (lo + hi + 1) / 2;
        if (texelFetch(cdf, ivec2(mid, row), 0).r <= u) {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    return lo;
}

// A direction drawn with density proportional to luminance (x texel solid angle): u.y picks the
// row, u.x the column; `pdf` is its solid-angle density (0 at an exact pole: skip the sample).
vec3 env_sample(vec2 u, out float pdf) {
    u = clamp(u, 0.0, 0.99999994);   // largest float32 below 1
    int w = u_env_size.x;
    int h = u_env_size.y;
    int i = env_search(u_env_marginal, 0, h, u.y);
    float m0 = texelFetch(u_env_marginal, ivec2(i, 0), 0).r;
    float m1 = texelFetch(u_env_marginal, ivec2(i + 1, 0), 0).r;
    int j = env_search(u_env_conditional, i, w, u.x);
    float c0 = texelFetch(u_env_conditional, ivec2(j, i), 0).r;
    float c1 = texelFetch(u_env_conditional, ivec2(j + 1, i), 0).r;
    // theta measured from the nearer pole (v or 1 - v, each from its own row edge): float32 keeps
    // sin(theta), hence the pdf, accurate to the poles instead of losing it to pi - theta rounding.
    bool south = 2 * i >= h;
    float edge = south ? (m1 - u.y) / (m1 - m0) : (u.y - m0) / (m1 - m0);
    float angle = ENV_PI * (float(south ? h - 1 - i : i) + edge) / float(h);
    float st = sin(angle);
    float ct = south ? -cos(angle) : cos(angle);
    float phi = 2.0 * ENV_PI * ((float(j) + (u.x - c0) / (c1 - c0)) / float(w) - 0.5);
    pdf = env_density(texelFetch(u_env_radiance, ivec2(j, i), 0).a, st);
    return vec3(st * sin(phi), ct, -st * cos(phi));
}

// Power heuristic (beta = 2) weight of a sample from the strategy with density a, against b;
// written as a ratio so huge densities do not overflow.
float mis_power(float a, float b) {
    if (a <= 0.0) return 0.0;
    if (b <= 0.0) return 1.0;
    if (a >= b) {
        float r = b / a;
        return 1.0 / (1.0 + r * r);
    }
    float r = a / b;
    return r * r / (1.0 + r * r);
}
