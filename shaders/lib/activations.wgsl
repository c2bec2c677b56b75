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
