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
