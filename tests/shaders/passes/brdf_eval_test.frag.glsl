// Test pass for lib/brdf: one sample per pixel, read from 6 texels side by side in u_inputs
// (data orientation): (l.xyz, v.x), (v.yz, base.xy), (base.z, roughness, metallic, anisotropic),
// (subsurface, specular, specular_tint, sheen), (sheen_tint, clearcoat, clearcoat_gloss, -),
// (n.h, alpha_h, -, -). Attachment 0: (disney_brdf(l, v).rgb, ggx(n.h, alpha_h)).
// Used by tests/models/test_brdf.py.
#define TEST_TEXELS 6
#include <lib/brdf>
#include <lib/test_pass>

layout(location = 0) out vec4 frag_out;

void main() {
    vec4 t[TEST_TEXELS];
    test_inputs(t);
    DisneyMaterial m;
    m.base_color = vec3(t[1].zw, t[2].x);
    m.roughness = t[2].y; m.metallic = t[2].z; m.anisotropic = t[2].w;
    m.subsurface = t[3].x; m.specular = t[3].y; m.specular_tint = t[3].z; m.sheen = t[3].w;
    m.sheen_tint = t[4].x; m.clearcoat = t[4].y; m.clearcoat_gloss = t[4].z;
    frag_out = vec4(disney_brdf(m, t[0].xyz, vec3(t[0].w, t[1].xy)), ggx(t[5].x, t[5].y));
}
