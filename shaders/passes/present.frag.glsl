// Present pass (viewer, page): a linear float image -> the window's 8-bit framebuffer: the tone mapper
// (u_tonemap, TONEMAP_*), then clip to [0, 1] and the sRGB OETF, as image_io.write_png does.
// u_origin is the lower-left corner of the viewport the image is drawn into, so texel (0, 0) lands on
// that corner; u_scale is the image's size over the viewport's (1: texel for pixel; less: a smaller
// image shown enlarged).
#include <lib/colour>
#include <lib/tonemap>

uniform sampler2D u_source;
uniform vec2 u_origin;
uniform vec2 u_scale;
uniform int u_tonemap;

layout(location = 0) out vec4 frag_color;

void main() {
    vec4 c = texelFetch(u_source, ivec2((gl_FragCoord.xy - u_origin) * u_scale), 0);
    frag_color = vec4(srgb_oetf(clamp(tonemap(u_tonemap, max(c.rgb, vec3(0.0))), 0.0, 1.0)), 1.0);
}
