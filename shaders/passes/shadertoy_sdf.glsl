// An SDF as a Shadertoy Image pass: lib/sdf's sphere tracing (the same march, hit test and normal
// taps as inshade render) from an orbit camera, the scene's (drag with the mouse to turn it), shaded
// as passes/sdf_diffuse.frag shades (albedo * E(n) / pi under the SH environment; the environment
// itself where the ray misses), times the scene's exposure, sRGB-encoded for display.
//
// Defines (written at the top of the pasted pass): SHADERTOY_TARGET, SHADERTOY_DISTANCE,
// SHADERTOY_YAW, SHADERTOY_PITCH, SHADERTOY_FOV_Y (the camera, degrees), SHADERTOY_EXPOSURE and
// SHADERTOY_SH (the environment's SH coefficients, an array constructor).
#include <lib/sdf>
#include <lib/spherical_harmonics>
#include <lib/colour>

const float SHADERTOY_INV_PI = 0.318309873;   // float32(1 / pi), as passes/sdf_diffuse.frag
const float SHADERTOY_DEG_PER_PIXEL = 0.3;    // a mouse drag turns the camera, as the viewer's does

// The orbit camera's view direction (scene/camera.py): yaw = pitch = 0 looks down -z.
vec3 shadertoy_direction(float yaw, float pitch) {
    float y = radians(yaw);
    float p = radians(pitch);
    return vec3(-sin(y) * cos(p), sin(p), -cos(y) * cos(p));
}

void mainImage(out vec4 fragColor, in vec2 fragCoord) {
    vec2 drag = iMouse.z > 0.0 ? (iMouse.xy - abs(iMouse.zw)) * SHADERTOY_DEG_PER_PIXEL : vec2(0.0);
    vec3 f = shadertoy_direction(SHADERTOY_YAW - drag.x, clamp(SHADERTOY_PITCH - drag.y, -89.0, 89.0));
    vec3 ro = SHADERTOY_TARGET - SHADERTOY_DISTANCE * f;
    vec3 right = normalize(cross(f, vec3(0.0, 1.0, 0.0)));
    vec3 up = cross(right, f);
    vec2 ndc = fragCoord * (2.0 / iResolution.xy) - 1.0;
    float h = tan(radians(SHADERTOY_FOV_Y) * 0.5);
    vec3 rd = normalize(f + (ndc.x * h * iResolution.x / iResolution.y) * right + (ndc.y * h) * up);
    vec3 sh[SH_COEFFS] = SHADERTOY_SH;
    float t;
    vec3 n;
    vec3 c;
    if (sdf_hit(ro, rd, t, n)) {
        c = scene_albedo(ro + rd * t) * sh_irradiance(n, sh) * SHADERTOY_INV_PI;
    } else {
        c = sh_background(rd, sh);
    }
    fragColor = vec4(srgb_oetf(clamp(c * SHADERTOY_EXPOSURE, 0.0, 1.0)), 1.0);
}
