// Copy pass: out = texture(u_source, v_uv). With a NEAREST-filtered source of the same size as
// the target, each pixel reads exactly its own texel, so float data round-trips bit-exactly.

uniform sampler2D u_source;

in vec2 v_uv;
out vec4 frag_color;

void main() {
    frag_color = texture(u_source, v_uv);
}
