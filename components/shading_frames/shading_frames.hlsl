// Learned shading frames in HLSL and Slang (shading_frames.glsl for OpenGL; torch_twin.py has the
// torch twin): the guarded normalise both sides use, finite at x = 0.
float3 inshade_frame_normalize(float3 x) { return x * rsqrt(max(dot(x, x), 1e-12)); }
