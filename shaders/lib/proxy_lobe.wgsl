// The importance-sampling proxy of Real-Time Neural Appearance Models in WGSL: only the functions of
// the proxy_params activation, which network code calls. The sampling routine and its density
// (proxy_lobe.glsl) are the techniques' OpenGL sampling code and have no WGSL version.
// Torch twin: models/proxy_lobe.py (same order of ops).

// Appendix A's quadratic tanh / sinh approximations (the proxy_params activation).
fn proxy_tanh_q(x: f32) -> f32 { return select(sign(x), x * (1.0 - 0.25 * abs(x)), abs(x) < 2.0); }
fn proxy_sinh_q(x: f32) -> f32 { return x * (1.0 + 0.25 * abs(x)); }
fn proxy_softmax2(own: f32, other: f32) -> f32 { return 1.0 / (1.0 + exp(other - own)); }
