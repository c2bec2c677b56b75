// Test pass for lib/proxy_lobe: one sample per pixel, read from 5 texels side by side in u_inputs
// (data orientation): params 0-3, params 4-7, (param 8, view.xyz), (u.xyz, -), (light.xyz, -).
// Attachment 0: (proxy_sample(p, view, u), proxy_pdf of that sample); attachment 1:
// (proxy_pdf(p, view, light), 0, 0, 0). Used by tests/components/test_proxy_lobe.py.
#define TEST_TEXELS 5
#include <lib/proxy_lobe>
#include <lib/test_pass>

layout(location = 0) out vec4 frag_out[2];

void main() {
    vec4 t[TEST_TEXELS];
    test_inputs(t);
    ProxyLobe lobe = proxy_lobe(t[0], t[1], t[2].x);
    vec3 view = t[2].yzw;
    vec3 light = proxy_sample(lobe, view, t[3].xyz);
    frag_out[0] = vec4(light, proxy_pdf(lobe, view, light));
    frag_out[1] = vec4(proxy_pdf(lobe, view, t[4].xyz), 0.0, 0.0, 0.0);
}
