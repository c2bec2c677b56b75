// Learned shading frames (torch_twin.py has the torch twin): the guarded normalise
// both sides use, finite at x = 0.
vec3 inshade_frame_normalize(vec3 x) { return x * inversesqrt(max(dot(x, x), 1e-12)); }
