// The peeled BLEND layers over the opaque surfaces: accumulated colour + transmittance x what the
// scene pass drew for the opaque layer (its alpha, the coverage, kept).
uniform sampler2D u_accum;
uniform sampler2D u_opaque;

layout(location = 0) out vec4 frag_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 acc = texelFetch(u_accum, px, 0);
    vec4 opaque = texelFetch(u_opaque, px, 0);
    frag_color = vec4(acc.rgb + acc.a * opaque.rgb, opaque.a);
}
