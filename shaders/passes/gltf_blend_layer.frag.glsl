// One peeled BLEND layer under what lies in front of it (front to back, the "under" operator): the
// accumulated (colour, transmittance) plus this layer's shaded colour weighed by its material alpha
// (lib/gltf_textures, at the layer's G-buffer uv and footprint) and the transmittance so far.
// Runtime: runtime/renderer.py, after the scene pass has shaded the layer's G-buffer.
#include <lib/gltf_textures>

uniform sampler2D u_accum;           // (sum of alpha-weighted colours so far, transmittance)
uniform sampler2D u_layer_colour;    // the scene pass over this layer's G-buffer
uniform sampler2D u_layer_uv;        // the layer's G-buffer uv: (u, v, material, coverage)
uniform sampler2D u_layer_uv_grad;   // its uv footprint (dFdx(uv), dFdy(uv))
#ifdef GBUFFER_UV1
uniform sampler2D u_layer_uv1;       // its second uv set and footprint (runtime/geometry.py)
uniform sampler2D u_layer_uv1_dy;
#endif

layout(location = 0) out vec4 frag_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 acc = texelFetch(u_accum, px, 0);
    vec4 uvm = texelFetch(u_layer_uv, px, 0);
    if (uvm.w <= 0.0) {
        frag_color = acc;
        return;
    }
    MaterialUV uv = material_uv(uvm.xy, texelFetch(u_layer_uv_grad, px, 0));
#ifdef GBUFFER_UV1
    material_uv1(uv, texelFetch(u_layer_uv1, px, 0), texelFetch(u_layer_uv1_dy, px, 0));
#endif
    float a = clamp(material_alpha(int(uvm.z + 0.5), uv), 0.0, 1.0);
    vec3 c = texelFetch(u_layer_colour, px, 0).rgb;
    frag_color = vec4(acc.rgb + acc.a * a * c, acc.a * (1.0 - a));
}
