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
