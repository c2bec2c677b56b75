// Activations and periodic functions whose plain GLSL forms overflow or lose precision.
// Torch twins: models/activations.py, models/encodings.py.

vec4 inshade_sigmoid(vec4 x) { return 1.0 / (1.0 + exp(-x)); }
float inshade_sigmoid(float x) { return 1.0 / (1.0 + exp(-x)); }

// exp(2x) overflows for |x| > 44; this form never does.
vec4 inshade_tanh(vec4 x) { vec4 e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }
float inshade_tanh(float x) { float e = exp(-2.0 * abs(x)); return sign(x) * (1.0 - e) / (1.0 + e); }

// softplus = max(x, 0) + log(1 + exp(-|x|)): finite for every finite x.
vec4 inshade_softplus(vec4 x) { return max(x, 0.0) + log(1.0 + exp(-abs(x))); }
float inshade_softplus(float x) { return max(x, 0.0) + log(1.0 + exp(-abs(x))); }

// Non-negative triangle wave, period 2, identity on [0, 1] (Differentiable Indirection's F).
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
