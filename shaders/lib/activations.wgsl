// Activations whose plain forms overflow or lose precision; the WGSL spelling of activations.glsl
// (the same formulas, vec4 forms only: WGSL has no overloads, a lane is passed as a vec4).

fn inshade_sigmoid(x: vec4<f32>) -> vec4<f32> { return 1.0 / (1.0 + exp(-x)); }

// exp(2x) overflows for |x| > 44; this form never does.
fn inshade_tanh(x: vec4<f32>) -> vec4<f32> { let e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }

// softplus = max(x, 0) + log(1 + exp(-|x|)): finite for every finite x.
fn inshade_softplus(x: vec4<f32>) -> vec4<f32> { return max(x, vec4<f32>(0.0)) + log(1.0 + exp(-abs(x))); }

// softplus with torch's beta and threshold: x where beta x > threshold, else softplus(beta x) / beta.
fn inshade_softplus_bt(x: vec4<f32>, beta: f32, threshold: f32) -> vec4<f32> {
    return select(inshade_softplus(beta * x) / beta, x, beta * x > vec4<f32>(threshold));
}

// sin / cos of an argument past pi, reduced by 2 pi first in three parts (Cody-Waite; see activations.glsl).
fn inshade_reduce_2pi(x: vec4<f32>) -> vec4<f32> {
    let k = round(x * 0.15915494);
    let r = ((x - k * 6.28125) - k * 1.9354820251464844e-3) + k * 1.7484555314695172e-7;
    return select(x, r, abs(k) < vec4<f32>(4096.0));
}
fn inshade_sin(x: vec4<f32>) -> vec4<f32> { return sin(inshade_reduce_2pi(x)); }
fn inshade_cos(x: vec4<f32>) -> vec4<f32> { return cos(inshade_reduce_2pi(x)); }

// x * sigmoid(x), as torch computes it: x / (1 + exp(-x)).
fn inshade_silu(x: vec4<f32>) -> vec4<f32> { return x / (1.0 + exp(-x)); }

// erf by Abramowitz & Stegun 7.1.26 (|error| <= 1.5e-7), odd-extended.
fn inshade_erf(x: vec4<f32>) -> vec4<f32> {
    let t = 1.0 / (1.0 + 0.3275911 * abs(x));
    let y = 1.0 - ((((1.061405429 * t - 1.453152027) * t + 1.421413741) * t - 0.284496736) * t + 0.254829592)
                  * t * exp(-x * x);
    return sign(x) * y;
}

// GELU, exact form x * (1 + erf(x / sqrt(2))) / 2 and torch's tanh approximation.
fn inshade_gelu(x: vec4<f32>) -> vec4<f32> { return 0.5 * x * (1.0 + inshade_erf(x * 0.707106781)); }
fn inshade_gelu_tanh(x: vec4<f32>) -> vec4<f32> {
    return 0.5 * x * (1.0 + inshade_tanh(0.797884561 * (x + 0.044715 * x * x * x)));
}

// ELU: x above 0, alpha (exp(x) - 1) below (exp of min(x, 0): no overflow on the unused side).
fn inshade_elu(x: vec4<f32>, alpha: f32) -> vec4<f32> {
    return select(alpha * (exp(min(x, vec4<f32>(0.0))) - 1.0), x, x > vec4<f32>(0.0));
}

// Non-negative triangle wave, period 2, identity on [0, 1] (Differentiable Indirection's F); GLSL's
// mod(t, 2) is t - 2 floor(t / 2).
fn inshade_triangle(t: vec4<f32>) -> vec4<f32> { return 1.0 - abs((t - 2.0 * floor(t / 2.0)) - 1.0); }

// --- torch's elementwise ops with their special values (the reasons: activations.glsl) ------------
// Special inputs are told apart by their bits (bitcast<u32>), not by float compares: drivers flush
// subnormals in float arithmetic and compares, and a compiler may fold compares as if NaN did not
// exist. One function per lane (*_lane), a vec4 form over them (WGSL has no overloads).

// NaN and inf from bits held in private variables: a constant expression may be neither in WGSL.
var<private> inshade_nan_bits: u32 = 0x7fc00000u;
var<private> inshade_inf_bits: u32 = 0x7f800000u;
fn inshade_nan() -> f32 { return bitcast<f32>(inshade_nan_bits); }
fn inshade_inf() -> f32 { return bitcast<f32>(inshade_inf_bits); }

// log and log2 as torch: NaN below 0, -inf at +-0, +inf at +inf; a subnormal x = m 2^-149 as
// log(m) - 149 ln 2 (a flushing driver would give -inf).
fn inshade_log_lane(x: f32) -> f32 {
    let b = bitcast<u32>(x);
    if ((b & 0x7fffffffu) == 0u) { return -inshade_inf(); }
    if (b >= 0x7f800000u) { return select(inshade_nan(), inshade_inf(), b == 0x7f800000u); }
    if (b < 0x00800000u) { return log(f32(b)) - 103.278929903; }
    return log(x);
}
fn inshade_log(x: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(inshade_log_lane(x.x), inshade_log_lane(x.y), inshade_log_lane(x.z), inshade_log_lane(x.w));
}
fn inshade_log2_lane(x: f32) -> f32 {
    let b = bitcast<u32>(x);
    if ((b & 0x7fffffffu) == 0u) { return -inshade_inf(); }
    if (b >= 0x7f800000u) { return select(inshade_nan(), inshade_inf(), b == 0x7f800000u); }
    if (b < 0x00800000u) { return log2(f32(b)) - 149.0; }
    return log2(x);
}
fn inshade_log2(x: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(inshade_log2_lane(x.x), inshade_log2_lane(x.y), inshade_log2_lane(x.z), inshade_log2_lane(x.w));
}

// floor and ceil with torch's values at subnormals: floor of a negative one is -1, ceil of a positive
// one 1 (b - first < count: an unsigned range test).
fn inshade_floor(x: vec4<f32>) -> vec4<f32> {
    return select(floor(x), vec4<f32>(-1.0), bitcast<vec4<u32>>(x) - 0x80000001u < vec4<u32>(0x007fffffu));
}
fn inshade_ceil(x: vec4<f32>) -> vec4<f32> {
    return select(ceil(x), vec4<f32>(1.0), bitcast<vec4<u32>>(x) - 1u < vec4<u32>(0x007fffffu));
}

// torch.fmod(x, c), exactly, on the integer mantissas (activations.glsl's inshade_fmod has the method).
fn inshade_fmod_lane(x: f32, c: f32) -> f32 {
    let bx = bitcast<u32>(x);
    let ax = bx & 0x7fffffffu;
    let ac = bitcast<u32>(c) & 0x7fffffffu;
    if (ax >= 0x7f800000u) { return inshade_nan(); }
    if (ax < ac) { return x; }
    let ex = max(ax >> 23u, 1u);
    let ec = max(ac >> 23u, 1u);
    let mx = (ax & 0x007fffffu) | select(0u, 0x00800000u, ax >= 0x00800000u);
    let mc = (ac & 0x007fffffu) | select(0u, 0x00800000u, ac >= 0x00800000u);
    var r = mx % mc;
    var d = ex - ec;
    while (d > 0u) {
        let s = min(d, 8u);
        r = (r << s) % mc;
        d -= s;
    }
    // r 2^(ec - 150) by moving float(r)'s exponent field; below 2^-126 flushed
    let fr = bitcast<u32>(f32(r));
    let e = i32(fr >> 23u) + i32(ec) - 150;
    let m = select((fr & 0x007fffffu) | (u32(max(e, 0)) << 23u), 0u, r == 0u || e <= 0);
    return bitcast<f32>(m | (bx & 0x80000000u));
}
fn inshade_fmod(x: vec4<f32>, c: f32) -> vec4<f32> {   // a loop over lanes (llvmpipe compiles loops apart)
    var r: vec4<f32>;
    for (var i = 0; i < 4; i++) { r[i] = inshade_fmod_lane(x[i], c); }
    return r;
}

// torch.remainder(x, c): fmod, plus c where that is non-zero and its sign differs from c's.
fn inshade_remainder_lane(x: f32, c: f32) -> f32 {
    let r = inshade_fmod_lane(x, c);
    let br = bitcast<u32>(r);
    if ((br & 0x7fffffffu) != 0u && (br >> 31u) != (bitcast<u32>(c) >> 31u)) { return r + c; }
    return r;
}
fn inshade_remainder(x: vec4<f32>, c: f32) -> vec4<f32> {
    var r: vec4<f32>;
    for (var i = 0; i < 4; i++) { r[i] = inshade_remainder_lane(x[i], c); }
    return r;
}

// x^n for an integer 0 < n < 64 by repeated squaring (written out: n is a constant, the steps fold).
fn inshade_powi(x0: f32, n: u32) -> f32 {
    var x = x0;
    var r = select(1.0, x, (n & 1u) != 0u);
    x *= x;
    if ((n & 2u) != 0u) { r *= x; }
    x *= x;
    if ((n & 4u) != 0u) { r *= x; }
    x *= x;
    if ((n & 8u) != 0u) { r *= x; }
    x *= x;
    if ((n & 16u) != 0u) { r *= x; }
    x *= x;
    if ((n & 32u) != 0u) { r *= x; }
    return r;
}
// log2 of a finite non-zero magnitude's bits (subnormals as in inshade_log2).
fn inshade_log2_bits(a: u32) -> f32 {
    if (a < 0x00800000u) { return log2(f32(a)) - 149.0; }
    return log2(bitcast<f32>(a));
}

// torch.pow(x, p) for a constant p: activations.glsl's inshade_pow, path for path.
fn inshade_pow_lane(x: f32, p: f32) -> f32 {
    if (p == 0.0) { return 1.0; }
    if (p == 1.0) { return x; }
    let b = bitcast<u32>(x);
    let a = b & 0x7fffffffu;
    let neg = b >= 0x80000000u;
    if (p == 0.5) { return select(sqrt(x), inshade_nan(), neg && a != 0u); }
    if (p == -0.5 || p == -1.0) {
        if (a == 0u) { return select(inshade_inf(), -inshade_inf(), neg); }   // 1 / sqrt(-0) = -inf, as torch
        if (p == -1.0) {
            if (a < 0x00800000u) { return select(8.50705917e37, -8.50705917e37, neg) / f32(a) * 8388608.0; }
            return 1.0 / x;
        }
        if (neg) { return inshade_nan(); }
        if (a < 0x00800000u) { return 3.77789319e22 / sqrt(2.0 * f32(a)); }   // 2^75 / sqrt(x 2^150)
        return 1.0 / sqrt(x);
    }
    let integer = p == trunc(p);
    if (integer && abs(p) <= 32.0) {
        if (p > 0.0) { return inshade_powi(x, u32(p)); }
        return inshade_powi(1.0 / x, u32(-p));
    }
    if (a > 0x7f800000u) { return inshade_nan(); }
    let odd = integer && abs(p) < 16777216.0 && abs(p % 2.0) == 1.0;   // % keeps the sign of p
    let s = select(1.0, -1.0, neg && odd);
    if (a == 0u) { return select(s * inshade_inf(), s * 0.0, p > 0.0); }
    if (a == 0x7f800000u) { return select(s * 0.0, s * inshade_inf(), p > 0.0); }
    if (neg && !integer) { return inshade_nan(); }
    if (a == 0x3f800000u) { return s; }              // |x| = 1: exactly, whatever p
    return s * exp2(p * inshade_log2_bits(a));
}
fn inshade_pow(x: vec4<f32>, p: f32) -> vec4<f32> {
    return vec4<f32>(inshade_pow_lane(x.x, p), inshade_pow_lane(x.y, p), inshade_pow_lane(x.z, p),
                     inshade_pow_lane(x.w, p));
}

// atan(a) for a in [0, 1]: Abramowitz & Stegun 4.4.49, |error| <= 2e-8 a before fp32 rounding.
fn inshade_atan01(a: f32) -> f32 {
    let z = a * a;
    return a * (1.0 + z * (-0.3333314528 + z * (0.1999355085 + z * (-0.1420889944 + z * (0.1065626393
           + z * (-0.0752896400 + z * (0.0429096138 + z * (-0.0161657367 + z * 0.0028662257))))))));
}
// |v| 2^100 exactly from v's magnitude bits (v below 2^-100; a subnormal m 2^-149 is m 2^-49).
fn inshade_scaled_up(a: u32) -> f32 {
    if (a < 0x00800000u) { return f32(a) * 1.77635684e-15; }
    return bitcast<f32>(a + 0x32000000u);
}
// torch.atan2(y, x), C's special values included (activations.glsl's inshade_atan2 has the method):
// the angle of |x|, |y| reduced to [0, pi/4], then reflected by the sign bits (-0 counts as negative).
fn inshade_atan2_lane(y: f32, x: f32) -> f32 {
    let by = bitcast<u32>(y);
    let bx = bitcast<u32>(x);
    let ay = by & 0x7fffffffu;
    let ax = bx & 0x7fffffffu;
    if (ay > 0x7f800000u || ax > 0x7f800000u) { return inshade_nan(); }
    let tiny = max(ay, ax) < 0x0d800000u;   // both below 2^-100: rescaled, so subnormals count
    let fy = select(bitcast<f32>(ay), inshade_scaled_up(ay), tiny);
    let fx = select(bitcast<f32>(ax), inshade_scaled_up(ax), tiny);
    let hi = max(fy, fx);
    let lo = min(fy, fx);
    // hi == lo: 1 also for inf / inf; hi == 0: (+-0, +-0)
    var t = inshade_atan01(select(select(lo / hi, 1.0, hi == lo), 0.0, hi == 0.0));
    if (fy > fx) { t = 1.57079637 - t; }
    if (bx >= 0x80000000u) { t = 3.14159274 - t; }
    return select(t, -t, by >= 0x80000000u);
}
fn inshade_atan2(y: vec4<f32>, x: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(inshade_atan2_lane(y.x, x.x), inshade_atan2_lane(y.y, x.y), inshade_atan2_lane(y.z, x.z),
                     inshade_atan2_lane(y.w, x.w));
}
