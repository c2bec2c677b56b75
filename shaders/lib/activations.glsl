// Activations and periodic functions whose plain GLSL forms overflow or lose precision.
// Torch twins: components/elementwise/torch_twin.py, models/encodings.py.

vec4 inshade_sigmoid(vec4 x) { return 1.0 / (1.0 + exp(-x)); }
float inshade_sigmoid(float x) { return 1.0 / (1.0 + exp(-x)); }

// exp(2x) overflows for |x| > 44; this form never does.
vec4 inshade_tanh(vec4 x) { vec4 e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }
float inshade_tanh(float x) { float e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }

// softplus = max(x, 0) + log(1 + exp(-|x|)): finite for every finite x.
vec4 inshade_softplus(vec4 x) { return max(x, 0.0) + log(1.0 + exp(-abs(x))); }
float inshade_softplus(float x) { return max(x, 0.0) + log(1.0 + exp(-abs(x))); }

// Non-negative triangle wave, period 2, identity on [0, 1] (Differentiable Indirection's F).
// sin / cos of an argument past pi: reduced by 2 pi first, in three parts (Cody-Waite: 2 pi = A + B + C
// with A and B of 8 and 12 significant bits, so k * A and k * B are exact for |k| < 2^12, |x| < 25,700),
// so the built-in only sees |r| <= ~pi, where drivers are most accurate (GPU sin/cos lose accuracy with
// |x|); past that range x goes to the built-in as it is. Codegen calls these where the plan's range of
// the argument passes pi (below it k = 0 and r = x).
float inshade_reduce_2pi(float x) {
    float k = roundEven(x * 0.15915494);
    float r = ((x - k * 6.28125) - k * 1.9354820251464844e-3) + k * 1.7484555314695172e-7;
    return abs(k) < 4096.0 ? r : x;
}
vec4 inshade_reduce_2pi(vec4 x) {
    vec4 k = roundEven(x * 0.15915494);
    vec4 r = ((x - k * 6.28125) - k * 1.9354820251464844e-3) + k * 1.7484555314695172e-7;
    return mix(x, r, lessThan(abs(k), vec4(4096.0)));
}
float inshade_sin(float x) { return sin(inshade_reduce_2pi(x)); }
vec4 inshade_sin(vec4 x) { return sin(inshade_reduce_2pi(x)); }
float inshade_cos(float x) { return cos(inshade_reduce_2pi(x)); }
vec4 inshade_cos(vec4 x) { return cos(inshade_reduce_2pi(x)); }

float inshade_triangle(float t) { return 1.0 - abs(mod(t, 2.0) - 1.0); }
vec4 inshade_triangle(vec4 t) { return 1.0 - abs(mod(t, 2.0) - 1.0); }

// x * sigmoid(x), as torch computes it: x / (1 + exp(-x)) (exp overflow gives -0, as torch).
vec4 inshade_silu(vec4 x) { return x / (1.0 + exp(-x)); }
float inshade_silu(float x) { return x / (1.0 + exp(-x)); }

// erf by Abramowitz & Stegun 7.1.26 (|error| <= 1.5e-7), odd-extended; GLSL has no erf.
float inshade_erf(float x) {
    float t = 1.0 / (1.0 + 0.3275911 * abs(x));
    float y = 1.0 - ((((1.061405429 * t - 1.453152027) * t + 1.421413741) * t - 0.284496736) * t + 0.254829592)
                    * t * exp(-x * x);
    return sign(x) * y;
}
vec4 inshade_erf(vec4 x) { return vec4(inshade_erf(x.x), inshade_erf(x.y), inshade_erf(x.z), inshade_erf(x.w)); }

// GELU, exact form x * (1 + erf(x / sqrt(2))) / 2 and torch's tanh approximation.
vec4 inshade_gelu(vec4 x) { return 0.5 * x * (1.0 + inshade_erf(x * 0.707106781)); }
float inshade_gelu(float x) { return 0.5 * x * (1.0 + inshade_erf(x * 0.707106781)); }
vec4 inshade_gelu_tanh(vec4 x) { return 0.5 * x * (1.0 + inshade_tanh(0.797884561 * (x + 0.044715 * x * x * x))); }
float inshade_gelu_tanh(float x) { return 0.5 * x * (1.0 + inshade_tanh(0.797884561 * (x + 0.044715 * x * x * x))); }

// ELU: x above 0, alpha (exp(x) - 1) below (exp of min(x, 0): no overflow on the unused side).
vec4 inshade_elu(vec4 x, float alpha) { return mix(alpha * (exp(min(x, 0.0)) - 1.0), x, greaterThan(x, vec4(0.0))); }
float inshade_elu(float x, float alpha) { return x > 0.0 ? x : alpha * (exp(x) - 1.0); }

// softplus with torch's beta and threshold: x where beta x > threshold, else softplus(beta x) / beta.
vec4 inshade_softplus(vec4 x, float beta, float threshold) {
    return mix(inshade_softplus(beta * x) / beta, x, greaterThan(beta * x, vec4(threshold)));
}
float inshade_softplus(float x, float beta, float threshold) {
    return beta * x > threshold ? x : inshade_softplus(beta * x) / beta;
}

// --- torch's elementwise ops with their special values --------------------------------------------
// Special inputs are told apart by their bits, not by float compares: drivers (llvmpipe, most GPUs)
// flush subnormals to zero in float arithmetic and compares, where torch's CPU kernels keep them,
// and a compiler may fold float compares as if NaN did not exist.

#define INSHADE_NAN uintBitsToFloat(0x7fc00000u)
#define INSHADE_INF uintBitsToFloat(0x7f800000u)

// log and log2 as torch: NaN below 0, -inf at +-0, +inf at +inf; a subnormal x = m 2^-149 as
// log(m) - 149 ln 2 (a flushing driver would give -inf).
float inshade_log(float x) {
    uint b = floatBitsToUint(x);
    if ((b & 0x7fffffffu) == 0u) return -INSHADE_INF;
    if (b >= 0x7f800000u) return b == 0x7f800000u ? INSHADE_INF : INSHADE_NAN;   // +inf; NaN or x < 0
    return b < 0x00800000u ? log(float(b)) - 103.278929903 : log(x);
}
vec4 inshade_log(vec4 x) { return vec4(inshade_log(x.x), inshade_log(x.y), inshade_log(x.z), inshade_log(x.w)); }
float inshade_log2(float x) {
    uint b = floatBitsToUint(x);
    if ((b & 0x7fffffffu) == 0u) return -INSHADE_INF;
    if (b >= 0x7f800000u) return b == 0x7f800000u ? INSHADE_INF : INSHADE_NAN;
    return b < 0x00800000u ? log2(float(b)) - 149.0 : log2(x);
}
vec4 inshade_log2(vec4 x) { return vec4(inshade_log2(x.x), inshade_log2(x.y), inshade_log2(x.z), inshade_log2(x.w)); }

// floor and ceil with torch's values at subnormals, which a flushing driver reads as 0: floor of a
// negative one is -1, ceil of a positive one 1 (b - first < count: an unsigned range test).
float inshade_floor(float x) { return floatBitsToUint(x) - 0x80000001u < 0x007fffffu ? -1.0 : floor(x); }
vec4 inshade_floor(vec4 x) {
    return mix(floor(x), vec4(-1.0), lessThan(floatBitsToUint(x) - 0x80000001u, uvec4(0x007fffffu)));
}
float inshade_ceil(float x) { return floatBitsToUint(x) - 1u < 0x007fffffu ? 1.0 : ceil(x); }
vec4 inshade_ceil(vec4 x) { return mix(ceil(x), vec4(1.0), lessThan(floatBitsToUint(x) - 1u, uvec4(0x007fffffu))); }

// torch.fmod(x, c), exactly (C's fmod: x - n c with n = trunc(x / c) taken exactly, the sign of x).
// With |x| = mx 2^ex and |c| = mc 2^ec (integer mantissas), |fmod| = ((mx 2^(ex - ec)) mod mc) 2^ec:
// the remainder is shifted left 8 bits at a time (r < mc < 2^24, so r << 8 fits 32 bits), one step
// per 8 binades of |x / c|. NaN for an infinite or NaN x; x itself where |x| < |c|. c must be normal.
float inshade_fmod(float x, float c) {
    uint bx = floatBitsToUint(x), ax = bx & 0x7fffffffu, ac = floatBitsToUint(c) & 0x7fffffffu;
    if (ax >= 0x7f800000u) return INSHADE_NAN;
    if (ax < ac) return x;                         // magnitudes order as their bits
    uint ex = max(ax >> 23, 1u), ec = max(ac >> 23, 1u);   // a subnormal's scale is a normal's lowest
    uint mx = (ax & 0x007fffffu) | (ax >= 0x00800000u ? 0x00800000u : 0u);
    uint mc = (ac & 0x007fffffu) | (ac >= 0x00800000u ? 0x00800000u : 0u);
    uint r = mx % mc;
    for (uint d = ex - ec; d > 0u; ) {
        uint s = min(d, 8u);
        r = (r << s) % mc;
        d -= s;
    }
    // r 2^(ec - 150): float(r) is exact (r < 2^24); its exponent field moved by ec - 150 (bits, not a
    // product with a power of two: a compiler may fold that into a constant a driver flushes); a result
    // below 2^-126 is flushed, as the driver's own arithmetic would
    uint fr = floatBitsToUint(float(r));
    int e = int(fr >> 23) + int(ec) - 150;
    uint m = r == 0u || e <= 0 ? 0u : (fr & 0x007fffffu) | (uint(e) << 23);
    return uintBitsToFloat(m | (bx & 0x80000000u));
}
// The lanes in a loop, not four inlined copies: llvmpipe's compile time grows ~2x per loop placed one
// after another in a shader (16 took a minute), but not for loops nested in a loop each.
vec4 inshade_fmod(vec4 x, float c) {
    vec4 r;
    for (int i = 0; i < 4; ++i) r[i] = inshade_fmod(x[i], c);
    return r;
}

// torch.remainder(x, c): fmod, plus c where that is non-zero and its sign differs from c's; one
// rounding, as torch (a tiny r of the other sign gives r + c = c, the end of [0, c) torch reaches).
float inshade_remainder(float x, float c) {
    float r = inshade_fmod(x, c);
    uint br = floatBitsToUint(r);
    return (br & 0x7fffffffu) != 0u && (br >> 31) != (floatBitsToUint(c) >> 31) ? r + c : r;
}
vec4 inshade_remainder(vec4 x, float c) {   // a loop over lanes, as inshade_fmod's
    vec4 r;
    for (int i = 0; i < 4; ++i) r[i] = inshade_remainder(x[i], c);
    return r;
}

// atan(a) for a in [0, 1]: Abramowitz & Stegun 4.4.49, |error| <= 2e-8 a before fp32 rounding.
float inshade_atan01(float a) {
    float z = a * a;
    return a * (1.0 + z * (-0.3333314528 + z * (0.1999355085 + z * (-0.1420889944 + z * (0.1065626393
           + z * (-0.0752896400 + z * (0.0429096138 + z * (-0.0161657367 + z * 0.0028662257))))))));
}
// |v| 2^100 exactly from v's magnitude bits (v below 2^-100; a subnormal m 2^-149 is m 2^-49).
float inshade_scaled_up(uint a) {
    return a < 0x00800000u ? float(a) * 1.77635684e-15 : uintBitsToFloat(a + 0x32000000u);
}

// torch.atan2(y, x), C's special values included: atan2(+-0, +0) = +-0, atan2(+-0, -0) = +-pi, the
// infinities (+-pi/4, +-3pi/4). GLSL's atan(y, x) is undefined at (0, 0) (llvmpipe gives 3pi/4) and
// 3.4e-6 off on llvmpipe; this is ~3e-7. The angle of |x|, |y| is reduced to [0, pi/4], then
// reflected by the signs (sign bits: -0 counts as negative, as in C).
float inshade_atan2(float y, float x) {
    uint by = floatBitsToUint(y), bx = floatBitsToUint(x);
    uint ay = by & 0x7fffffffu, ax = bx & 0x7fffffffu;
    if (ay > 0x7f800000u || ax > 0x7f800000u) return INSHADE_NAN;
    bool tiny = max(ay, ax) < 0x0d800000u;   // both below 2^-100: rescaled, so subnormals count
    float fy = tiny ? inshade_scaled_up(ay) : uintBitsToFloat(ay);
    float fx = tiny ? inshade_scaled_up(ax) : uintBitsToFloat(ax);
    float hi = max(fy, fx), lo = min(fy, fx);
    // hi == lo: 1 also for inf / inf; hi == 0: (+-0, +-0)
    float t = inshade_atan01(hi == 0.0 ? 0.0 : (hi == lo ? 1.0 : lo / hi));
    if (fy > fx) t = 1.57079637 - t;
    if (bx >= 0x80000000u) t = 3.14159274 - t;
    return by >= 0x80000000u ? -t : t;
}
vec4 inshade_atan2(vec4 y, vec4 x) {
    return vec4(inshade_atan2(y.x, x.x), inshade_atan2(y.y, x.y), inshade_atan2(y.z, x.z), inshade_atan2(y.w, x.w));
}

// x^n for an integer 0 < n < 64 by repeated squaring: n - 1 roundings at most (x^2 = x*x and x^3 =
// x*x*x bit for bit as torch computes them). Written out, not a loop: n is a constant, so the steps
// fold, and llvmpipe's compile time grows ~2x per loop in a shader.
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
float inshade_log2_bits(uint a) { return a < 0x00800000u ? log2(float(a)) - 149.0 : log2(uintBitsToFloat(a)); }

// torch.pow(x, p) for a constant p (the branches on p fold away): torch's own paths for p = 0, 1,
// 0.5, -0.5, -1 (1, x, sqrt, 1 / sqrt, 1 / x; -0.5 and -1 of a subnormal from its bits); an integer p
// with |p| <= 32 by repeated squaring (of 1 / x for p < 0); otherwise C's pow: |x|^p = exp2(p log2 |x|)
// (relative error growing with |p log2 |x||: inshade/envelope.py's POW_ARG), negated for an odd
// integer p and x < 0, NaN for x < 0 and a non-integer p, and the zeros and infinities explicit.
float inshade_pow(float x, float p) {
    if (p == 0.0) return 1.0;
    if (p == 1.0) return x;
    uint b = floatBitsToUint(x), a = b & 0x7fffffffu;
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
    bool odd = integer && abs(p) < 16777216.0 && mod(p, 2.0) == 1.0;
    float s = neg && odd ? -1.0 : 1.0;
    if (a == 0u) return p > 0.0 ? s * 0.0 : s * INSHADE_INF;
    if (a == 0x7f800000u) return p > 0.0 ? s * INSHADE_INF : s * 0.0;
    if (neg && !integer) return INSHADE_NAN;
    if (a == 0x3f800000u) return s;               // |x| = 1: exactly, whatever p
    return s * exp2(p * inshade_log2_bits(a));
}
vec4 inshade_pow(vec4 x, float p) {
    return vec4(inshade_pow(x.x, p), inshade_pow(x.y, p), inshade_pow(x.z, p), inshade_pow(x.w, p));
}
