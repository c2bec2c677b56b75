// Activations whose plain forms overflow or lose precision; the HLSL (and Slang) spelling of
// activations.glsl: the same formulas, float4 and float overloads.

// A lane-wise choice: select() where the language has it (Slang, HLSL 2021), the vector ?: of
// Shader Model 5 elsewhere.
#if defined(__SLANG__) || (defined(__HLSL_VERSION) && __HLSL_VERSION >= 2021)
#define INSHADE_SELECT(c, a, b) select(c, a, b)
#else
#define INSHADE_SELECT(c, a, b) ((c) ? (a) : (b))
#endif

float4 inshade_sigmoid(float4 x) { return 1.0 / (1.0 + exp(-x)); }
float inshade_sigmoid(float x) { return 1.0 / (1.0 + exp(-x)); }

// exp(2x) overflows for |x| > 44; this form never does.
float4 inshade_tanh(float4 x) { float4 e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }
float inshade_tanh(float x) { float e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }

// softplus = max(x, 0) + log(1 + exp(-|x|)): finite for every finite x.
float4 inshade_softplus(float4 x) { return max(x, 0.0) + log(1.0 + exp(-abs(x))); }
float inshade_softplus(float x) { return max(x, 0.0) + log(1.0 + exp(-abs(x))); }

// softplus with torch's beta and threshold: x where beta x > threshold, else softplus(beta x) / beta.
float4 inshade_softplus(float4 x, float beta, float threshold) {
    return INSHADE_SELECT(beta * x > threshold, x, inshade_softplus(beta * x) / beta);
}
float inshade_softplus(float x, float beta, float threshold) {
    return beta * x > threshold ? x : inshade_softplus(beta * x) / beta;
}

// sin / cos of an argument past pi, reduced by 2 pi first in three parts (Cody-Waite; see activations.glsl).
float4 inshade_reduce_2pi(float4 x) {
    float4 k = round(x * 0.15915494);
    float4 r = ((x - k * 6.28125) - k * 1.9354820251464844e-3) + k * 1.7484555314695172e-7;
    return INSHADE_SELECT(abs(k) < 4096.0, r, x);
}
float inshade_reduce_2pi(float x) {
    float k = round(x * 0.15915494);
    float r = ((x - k * 6.28125) - k * 1.9354820251464844e-3) + k * 1.7484555314695172e-7;
    return abs(k) < 4096.0 ? r : x;
}
float4 inshade_sin(float4 x) { return sin(inshade_reduce_2pi(x)); }
float inshade_sin(float x) { return sin(inshade_reduce_2pi(x)); }
float4 inshade_cos(float4 x) { return cos(inshade_reduce_2pi(x)); }
float inshade_cos(float x) { return cos(inshade_reduce_2pi(x)); }

// x * sigmoid(x), as torch computes it: x / (1 + exp(-x)).
float4 inshade_silu(float4 x) { return x / (1.0 + exp(-x)); }
float inshade_silu(float x) { return x / (1.0 + exp(-x)); }

// erf by Abramowitz & Stegun 7.1.26 (|error| <= 1.5e-7), odd-extended.
float4 inshade_erf(float4 x) {
    float4 t = 1.0 / (1.0 + 0.3275911 * abs(x));
    float4 y = 1.0 - ((((1.061405429 * t - 1.453152027) * t + 1.421413741) * t - 0.284496736) * t + 0.254829592)
                     * t * exp(-x * x);
    return sign(x) * y;
}
float inshade_erf(float x) { return inshade_erf(((float4)x)).x; }

// GELU, exact form x * (1 + erf(x / sqrt(2))) / 2 and torch's tanh approximation.
float4 inshade_gelu(float4 x) { return 0.5 * x * (1.0 + inshade_erf(x * 0.707106781)); }
float inshade_gelu(float x) { return 0.5 * x * (1.0 + inshade_erf(x * 0.707106781)); }
float4 inshade_gelu_tanh(float4 x) { return 0.5 * x * (1.0 + inshade_tanh(0.797884561 * (x + 0.044715 * x * x * x))); }
float inshade_gelu_tanh(float x) { return 0.5 * x * (1.0 + inshade_tanh(0.797884561 * (x + 0.044715 * x * x * x))); }

// ELU: x above 0, alpha (exp(x) - 1) below (exp of min(x, 0): no overflow on the unused side).
float4 inshade_elu(float4 x, float alpha) { return INSHADE_SELECT(x > 0.0, x, alpha * (exp(min(x, 0.0)) - 1.0)); }
float inshade_elu(float x, float alpha) { return x > 0.0 ? x : alpha * (exp(x) - 1.0); }

// Non-negative triangle wave, period 2, identity on [0, 1] (Differentiable Indirection's F); GLSL's
// mod(t, 2) is t - 2 floor(t / 2) (HLSL's fmod truncates).
float4 inshade_triangle(float4 t) { return 1.0 - abs((t - 2.0 * floor(t / 2.0)) - 1.0); }
float inshade_triangle(float t) { return 1.0 - abs((t - 2.0 * floor(t / 2.0)) - 1.0); }

// --- torch's elementwise ops with their special values (the reasons: activations.glsl) ------------
// Special inputs are told apart by their bits (asuint), not by float compares: drivers flush
// subnormals in float arithmetic and compares, and a compiler may fold compares as if NaN did not exist.

// NaN and inf from bits held in variables: a compiler folds asfloat of a constant into a literal, and
// SPIR-V readers (naga) refuse an infinite or NaN literal. INSHADE_MEMBERS: these functions are
// members of a struct (an Unreal Custom node's), whose user sets the two members to the bits below.
#define INSHADE_NAN_BITS 0x7fc00000u
#define INSHADE_INF_BITS 0x7f800000u
#ifdef INSHADE_MEMBERS
uint inshade_nan_bits;
uint inshade_inf_bits;
#else
static uint inshade_nan_bits = INSHADE_NAN_BITS;
static uint inshade_inf_bits = INSHADE_INF_BITS;
#endif
#define INSHADE_NAN asfloat(inshade_nan_bits)
#define INSHADE_INF asfloat(inshade_inf_bits)

// log and log2 as torch: NaN below 0, -inf at +-0, +inf at +inf; a subnormal x = m 2^-149 as
// log(m) - 149 ln 2 (a flushing driver would give -inf).
float inshade_log(float x) {
    uint b = asuint(x);
    if ((b & 0x7fffffffu) == 0u) return -INSHADE_INF;
    if (b >= 0x7f800000u) return b == 0x7f800000u ? INSHADE_INF : INSHADE_NAN;   // +inf; NaN or x < 0
    return b < 0x00800000u ? log(float(b)) - 103.278929903 : log(x);
}
float4 inshade_log(float4 x) { return float4(inshade_log(x.x), inshade_log(x.y), inshade_log(x.z), inshade_log(x.w)); }
float inshade_log2(float x) {
    uint b = asuint(x);
    if ((b & 0x7fffffffu) == 0u) return -INSHADE_INF;
    if (b >= 0x7f800000u) return b == 0x7f800000u ? INSHADE_INF : INSHADE_NAN;
    return b < 0x00800000u ? log2(float(b)) - 149.0 : log2(x);
}
float4 inshade_log2(float4 x) {
    return float4(inshade_log2(x.x), inshade_log2(x.y), inshade_log2(x.z), inshade_log2(x.w));
}

// floor and ceil with torch's values at subnormals: floor of a negative one is -1, ceil of a positive
// one 1 (b - first < count: an unsigned range test).
float inshade_floor(float x) { return asuint(x) - 0x80000001u < 0x007fffffu ? -1.0 : floor(x); }
float4 inshade_floor(float4 x) { return INSHADE_SELECT(asuint(x) - 0x80000001u < 0x007fffffu, ((float4)-1.0), floor(x)); }
float inshade_ceil(float x) { return asuint(x) - 1u < 0x007fffffu ? 1.0 : ceil(x); }
float4 inshade_ceil(float4 x) { return INSHADE_SELECT(asuint(x) - 1u < 0x007fffffu, ((float4)1.0), ceil(x)); }

// torch.fmod(x, c), exactly, on the integer mantissas (activations.glsl's inshade_fmod has the method).
float inshade_fmod(float x, float c) {
    uint bx = asuint(x), ax = bx & 0x7fffffffu, ac = asuint(c) & 0x7fffffffu;
    if (ax >= 0x7f800000u) return INSHADE_NAN;
    if (ax < ac) return x;
    uint ex = max(ax >> 23, 1u), ec = max(ac >> 23, 1u);
    uint mx = (ax & 0x007fffffu) | (ax >= 0x00800000u ? 0x00800000u : 0u);
    uint mc = (ac & 0x007fffffu) | (ac >= 0x00800000u ? 0x00800000u : 0u);
    uint r = mx % mc;
    for (uint d = ex - ec; d > 0u; ) {
        uint s = min(d, 8u);
        r = (r << s) % mc;
        d -= s;
    }
    // r 2^(ec - 150) by moving float(r)'s exponent field; below 2^-126 flushed
    uint fr = asuint(float(r));
    int e = int(fr >> 23) + int(ec) - 150;
    uint m = r == 0u || e <= 0 ? 0u : (fr & 0x007fffffu) | (uint(e) << 23);
    return asfloat(m | (bx & 0x80000000u));
}
float4 inshade_fmod(float4 x, float c) {   // a loop over lanes (llvmpipe compiles loops apart)
    float4 r;
    for (int i = 0; i < 4; ++i) r[i] = inshade_fmod(x[i], c);
    return r;
}

// torch.remainder(x, c): fmod, plus c where that is non-zero and its sign differs from c's.
float inshade_remainder(float x, float c) {
    float r = inshade_fmod(x, c);
    uint br = asuint(r);
    return (br & 0x7fffffffu) != 0u && (br >> 31) != (asuint(c) >> 31) ? r + c : r;
}
float4 inshade_remainder(float4 x, float c) {
    float4 r;
    for (int i = 0; i < 4; ++i) r[i] = inshade_remainder(x[i], c);
    return r;
}

// x^n for an integer 0 < n < 64 by repeated squaring (written out: n is a constant, the steps fold).
float inshade_powi(float x, uint n) {
    float r = (n & 1u) != 0u ? x : 1.0;
    x *= x;
    if ((n & 2u) != 0u) r *= x;
    x *= x;
    if ((n & 4u) != 0u) r *= x;
    x *= x;
    if ((n & 8u) != 0u) r *= x;
    x *= x;
    if ((n & 16u) != 0u) r *= x;
    x *= x;
    if ((n & 32u) != 0u) r *= x;
    return r;
}
// log2 of a finite non-zero magnitude's bits (subnormals as in inshade_log2).
float inshade_log2_bits(uint a) { return a < 0x00800000u ? log2(float(a)) - 149.0 : log2(asfloat(a)); }

// torch.pow(x, p) for a constant p: activations.glsl's inshade_pow, path for path.
float inshade_pow(float x, float p) {
    if (p == 0.0) return 1.0;
    if (p == 1.0) return x;
    uint b = asuint(x), a = b & 0x7fffffffu;
    bool neg = b >= 0x80000000u;
    if (p == 0.5) return neg && a != 0u ? INSHADE_NAN : sqrt(x);
    if (p == -0.5) {
        if (a == 0u) return neg ? -INSHADE_INF : INSHADE_INF;      // 1 / sqrt(-0) = -inf, as torch
        if (neg) return INSHADE_NAN;
        return a < 0x00800000u ? 3.77789319e22 / sqrt(2.0 * float(a)) : 1.0 / sqrt(x);   // 2^75 / sqrt(x 2^150)
    }
    if (p == -1.0) {
        if (a == 0u) return neg ? -INSHADE_INF : INSHADE_INF;
        if (a < 0x00800000u) return (neg ? -8.50705917e37 : 8.50705917e37) / float(a) * 8388608.0;   // 2^126 / m * 2^23
        return 1.0 / x;
    }
    bool integer = p == trunc(p);
    if (integer && abs(p) <= 32.0) return p > 0.0 ? inshade_powi(x, uint(p)) : inshade_powi(1.0 / x, uint(-p));
    if (a > 0x7f800000u) return INSHADE_NAN;
    bool odd = integer && abs(p) < 16777216.0 && abs(fmod(p, 2.0)) == 1.0;   // fmod keeps the sign of p
    float s = neg && odd ? -1.0 : 1.0;
    if (a == 0u) return p > 0.0 ? s * 0.0 : s * INSHADE_INF;
    if (a == 0x7f800000u) return p > 0.0 ? s * INSHADE_INF : s * 0.0;
    if (neg && !integer) return INSHADE_NAN;
    if (a == 0x3f800000u) return s;               // |x| = 1: exactly, whatever p
    return s * exp2(p * inshade_log2_bits(a));
}
float4 inshade_pow(float4 x, float p) {
    return float4(inshade_pow(x.x, p), inshade_pow(x.y, p), inshade_pow(x.z, p), inshade_pow(x.w, p));
}

// atan(a) for a in [0, 1]: Abramowitz & Stegun 4.4.49, |error| <= 2e-8 a before fp32 rounding.
float inshade_atan01(float a) {
    float z = a * a;
    return a * (1.0 + z * (-0.3333314528 + z * (0.1999355085 + z * (-0.1420889944 + z * (0.1065626393
           + z * (-0.0752896400 + z * (0.0429096138 + z * (-0.0161657367 + z * 0.0028662257))))))));
}
// |v| 2^100 exactly from v's magnitude bits (v below 2^-100; a subnormal m 2^-149 is m 2^-49).
float inshade_scaled_up(uint a) { return a < 0x00800000u ? float(a) * 1.77635684e-15 : asfloat(a + 0x32000000u); }

// torch.atan2(y, x), C's special values included (activations.glsl's inshade_atan2 has the method):
// the angle of |x|, |y| reduced to [0, pi/4], then reflected by the sign bits (-0 counts as negative).
float inshade_atan2(float y, float x) {
    uint by = asuint(y), bx = asuint(x);
    uint ay = by & 0x7fffffffu, ax = bx & 0x7fffffffu;
    if (ay > 0x7f800000u || ax > 0x7f800000u) return INSHADE_NAN;
    bool tiny = max(ay, ax) < 0x0d800000u;   // both below 2^-100: rescaled, so subnormals count
    float fy = tiny ? inshade_scaled_up(ay) : asfloat(ay);
    float fx = tiny ? inshade_scaled_up(ax) : asfloat(ax);
    float hi = max(fy, fx), lo = min(fy, fx);
    // hi == lo: 1 also for inf / inf; hi == 0: (+-0, +-0)
    float t = inshade_atan01(hi == 0.0 ? 0.0 : (hi == lo ? 1.0 : lo / hi));
    if (fy > fx) t = 1.57079637 - t;
    if (bx >= 0x80000000u) t = 3.14159274 - t;
    return by >= 0x80000000u ? -t : t;
}
float4 inshade_atan2(float4 y, float4 x) {
    return float4(inshade_atan2(y.x, x.x), inshade_atan2(y.y, x.y), inshade_atan2(y.z, x.z), inshade_atan2(y.w, x.w));
}
