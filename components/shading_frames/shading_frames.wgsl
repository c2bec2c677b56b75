// Learned shading frames in WGSL (shading_frames.glsl for OpenGL; torch_twin.py has the torch twin):
// the guarded normalise both sides use, finite at x = 0.
fn inshade_frame_normalize(x: vec3<f32>) -> vec3<f32> { return x * inverseSqrt(max(dot(x, x), 1e-12)); }
