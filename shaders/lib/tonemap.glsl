// Tone mappers (inshade.scene.tonemap, which has the numpy twins): linear values -> [0, 1] for a
// display, run once where the picture is presented (never on the float image).
#include <tonemaps>

vec3 tonemap_reinhard(vec3 c) {
    return c / (1.0 + c);
}

// Khronos PBR Neutral: unchanged up to 0.76, then compressed towards white with some desaturation.
vec3 tonemap_pbr_neutral(vec3 c) {
    const float start = 0.8 - 0.04;
    const float desaturation = 0.15;
    float x = min(c.r, min(c.g, c.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    c -= offset;
    float peak = max(c.r, max(c.g, c.b));
    if (peak < start) return c;
    const float d = 1.0 - start;
    float new_peak = 1.0 - d * d / (peak + d - start);
    c *= new_peak / peak;
    float g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
    return mix(c, vec3(new_peak), g);
}

vec3 tonemap(int op, vec3 c) {
    if (op == TONEMAP_REINHARD) return tonemap_reinhard(c);
    if (op == TONEMAP_PBR_NEUTRAL) return tonemap_pbr_neutral(c);
    return c;
}
