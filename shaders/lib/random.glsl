// Per-pixel random numbers for stochastic (accumulating) programs: one Monte Carlo sample per pixel
// per draw, seeded by the pixel, the sample index since the last reset (u_sample_index) and a
// stream number (one per independent use in a program). numpy twin: inshade/random.py, bit-identical.

// PCG-RXS-M-XS 32-bit output permutation of one LCG step (Jarzynski & Olano, "Hash Functions for
// GPU Rendering", JCGT 2020): a cheap hash whose outputs pass statistical tests.
uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The hash chain's start for (pixel, sample, stream): nested hashing so that nearby seeds
// (neighbouring pixels, consecutive samples) give unrelated numbers.
uint random_seed(uvec2 pixel, int sample_index, int stream) {
    return pcg(pixel.x + pcg(pixel.y + pcg(uint(sample_index) + pcg(uint(stream)))));
}

// The top 24 bits as a float in [0, 1): exact in float32 (24-bit mantissa), never 1.0.
float random_unit(uint h) {
    return float(h >> 8u) * (1.0 / 16777216.0);
}

// Uniform [0, 1) numbers; component k hashes the seed k + 1 times, so random_uniform2 is the first
// two components of random_uniform4 with the same arguments. (GLSL cannot overload on the return
// type alone, hence the suffixes.)
float random_uniform(uvec2 pixel, int sample_index, int stream) {
    return random_unit(pcg(random_seed(pixel, sample_index, stream)));
}

vec2 random_uniform2(uvec2 pixel, int sample_index, int stream) {
    uint h0 = pcg(random_seed(pixel, sample_index, stream));
    uint h1 = pcg(h0);
    return vec2(random_unit(h0), random_unit(h1));
}

vec3 random_uniform3(uvec2 pixel, int sample_index, int stream) {
    uint h0 = pcg(random_seed(pixel, sample_index, stream));
    uint h1 = pcg(h0);
    uint h2 = pcg(h1);
    return vec3(random_unit(h0), random_unit(h1), random_unit(h2));
}

vec4 random_uniform4(uvec2 pixel, int sample_index, int stream) {
    uint h0 = pcg(random_seed(pixel, sample_index, stream));
    uint h1 = pcg(h0);
    uint h2 = pcg(h1);
    uint h3 = pcg(h2);
    return vec4(random_unit(h0), random_unit(h1), random_unit(h2), random_unit(h3));
}
