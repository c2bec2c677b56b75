// The importance-sampling proxy of Real-Time Neural Appearance Models in HLSL and Slang: only the
// functions of the proxy_params activation, which network code calls. The sampling routine and its
// density (proxy_lobe.glsl) are the techniques' OpenGL sampling code and have no HLSL version.
// Torch twin: models/proxy_lobe.py (same order of ops).

// Appendix A's quadratic tanh / sinh approximations (the proxy_params activation).
float proxy_tanh_q(float x) { return abs(x) < 2.0 ? x * (1.0 - 0.25 * abs(x)) : float(sign(x)); }
float proxy_sinh_q(float x) { return x * (1.0 + 0.25 * abs(x)); }
float proxy_softmax2(float own, float other) { return 1.0 / (1.0 + exp(other - own)); }
