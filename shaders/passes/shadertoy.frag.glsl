// Runs a pasted Shadertoy Image pass (chunk <shadertoy_pass>) as shadertoy.com does: its uniforms,
// then the pass, then a main that calls mainImage at the pixel centre and shows alpha 1. The
// uniforms a check does not set keep their zero (iTime 0, no mouse, empty channels).
//
// SHADERTOY_NETWORK: main writes the pass's network colour itself (shadertoy_colour at
// gl_FragCoord.xy / iResolution.xy, unclamped and unencoded) for the parity check.
uniform vec3 iResolution;
uniform float iTime;
uniform float iTimeDelta;
uniform float iFrameRate;
uniform int iFrame;
uniform float iChannelTime[4];
uniform vec3 iChannelResolution[4];
uniform vec4 iMouse;
uniform vec4 iDate;
uniform float iSampleRate;
uniform sampler2D iChannel0;
uniform sampler2D iChannel1;
uniform sampler2D iChannel2;
uniform sampler2D iChannel3;

#include <shadertoy_pass>

layout(location = 0) out vec4 shadertoy_out;

void main() {
#ifdef SHADERTOY_NETWORK
    shadertoy_out = shadertoy_colour(gl_FragCoord.xy / iResolution.xy);
#else
    vec4 color = vec4(0.0, 0.0, 0.0, 1.0);
    mainImage(color, gl_FragCoord.xy);
    shadertoy_out = vec4(color.rgb, 1.0);
#endif
}
